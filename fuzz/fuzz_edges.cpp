// libFuzzer target: edge capture readers (logic-analyzer CSV and one-time-per-line list), first byte selects.
#include "edge_file_source.hpp"
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const torqued::fuzz::MemFile f(data + 1, size - 1);
  torqued::EdgeEvent e;
  if (data[0] & 1) {
    torqued::EdgeListSource src(f.path());
    while (src.ok() && src.next(e) == torqued::SourceStatus::kOk) {
    }
  } else {
    torqued::EdgeCsvSource src(f.path());
    while (src.ok() && src.next(e) == torqued::SourceStatus::kOk) {
    }
  }
  return 0;
}

// libFuzzer target: candump -l log reader.
#include "candump_source.hpp"
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const torqued::fuzz::MemFile f(data, size);
  torqued::CandumpSource src(f.path());
  torqued::CanFrame fr;
  while (src.ok() && src.next(fr) == torqued::SourceStatus::kOk) {
  }
  return 0;
}

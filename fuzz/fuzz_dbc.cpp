// libFuzzer target: DBC parser, then the decoding of every signal of every message from the input's bytes.
#include <algorithm>
#include <array>
#include <string_view>

#include "dbc.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const torqued::DbcParseResult r = torqued::DbcDatabase::parse_string(text, "fuzz.dbc");
  if (!r.db) return 0;
  std::array<std::uint8_t, 64> payload{};
  std::copy_n(data, std::min(size, payload.size()), payload.begin());
  for (const auto& m : r.db->messages())
    for (const auto& s : m.signals)
      if (s.bytes_needed() <= payload.size() && m.signal_present(s, payload.data(), payload.size()))
        (void)s.decode(payload.data(), payload.size());
  return 0;
}

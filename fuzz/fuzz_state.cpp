// libFuzzer target: learned-state loader (format, checksum) and its identity/physical-bound checks.
#include <string>

#include "config.hpp"
#include "state_store.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const torqued::StateContext ctx = torqued::state_context_from(torqued::Config{});
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::string err;
  if (auto s = torqued::parse_state(text, "fuzz", &err)) {
    (void)torqued::check_state(*s, ctx, "fuzz", &err);
    // What parses must serialize and parse back to the same values: every line of the table (the same text
    // again).
    const std::string text = torqued::serialize_state(*s, ctx.identity);
    const auto again = torqued::parse_state(text, "again", &err);
    if (!again || torqued::serialize_state(*again, ctx.identity) != text ||
        again->tooth_corrections_rad != s->tooth_corrections_rad || again->friction != s->friction)
      __builtin_trap();
  }
  return 0;
}

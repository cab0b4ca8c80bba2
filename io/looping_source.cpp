#include "looping_source.hpp"

#include <algorithm>

namespace torqued {

std::int64_t loop_period_ns(EdgeSource& edges, CanSource* can, std::int64_t can_offset_ns) {
  EdgeEvent e{};
  std::int64_t first = 0, last = 0, prev = 0;
  std::uint64_t n = 0;
  while (edges.next(e) == SourceStatus::kOk) {
    if (n == 0) first = e.t_ns;
    prev = last;
    last = e.t_ns;
    ++n;
  }
  if (n < 2) return 0;
  const std::int64_t last_gap_ns = std::max<std::int64_t>(last - prev, 1);
  if (can != nullptr) {
    CanFrame f{};
    while (can->next(f) == SourceStatus::kOk) {
      first = std::min(first, f.t_ns + can_offset_ns);
      last = std::max(last, f.t_ns + can_offset_ns);
    }
  }
  return last - first + last_gap_ns;
}

}  // namespace torqued

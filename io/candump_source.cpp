#include "candump_source.hpp"

#include <algorithm>
#include <cstring>

#include "fast_parse.hpp"

namespace torqued {
namespace {
constexpr std::size_t kMaxMessages = 20;

bool valid_fd_len(int n) noexcept {
  return n <= 8 || n == 12 || n == 16 || n == 20 || n == 24 || n == 32 || n == 48 || n == 64;
}
}  // namespace

CandumpSource::CandumpSource(std::string path, CandumpOptions options)
    : path_(std::move(path)), opt_(options), sanity_(opt_.time) {
  messages_.reserve(kMaxMessages);
  ok_ = reader_.open(path_);
  if (!ok_) error_ = reader_.error();
}

std::string CandumpSource::describe() const { return "candump " + path_; }

std::string_view CandumpSource::bus_name(std::uint8_t bus) const noexcept {
  if (bus >= buses_) return {};
  return std::string_view(bus_names_[bus].data(), bus_name_len_[bus]);  // as matched: the bytes stored
}

const char* CandumpSource::parse_line(std::string_view line, CanFrame& out,
                                      std::string_view& bus_name) noexcept {
  const char* p = line.data();
  const char* end = p + line.size();
  parse::skip_ws(p, end);
  if (p == end || *p != '(') return "expected '(<seconds>) <interface> <id>#<data>'";
  ++p;
  std::int64_t t = 0;
  if (!parse::seconds_to_ns(p, end, t) || p == end || *p != ')') return "expected a timestamp '(<seconds>)'";
  ++p;
  parse::skip_ws(p, end);
  const char* name = p;
  while (p < end && *p != ' ' && *p != '\t') ++p;
  if (p == name) return "expected an interface name after the timestamp";
  bus_name = std::string_view(name, static_cast<std::size_t>(p - name));
  parse::skip_ws(p, end);
  const char* id_start = p;
  std::uint32_t id = 0;
  int d = 0;
  while (p < end && (d = parse::hex_digit(*p)) >= 0) {
    id = (id << 4) | static_cast<std::uint32_t>(d);
    ++p;
  }
  const auto id_len = p - id_start;
  if (p == end || *p != '#' || id_len == 0) return "expected '<hex id>#' after the interface";
  out = CanFrame{};
  out.t_ns = t;
  if (id_len == 8) {
    if (id > 0x1FFFFFFFu) return "extended id above 0x1FFFFFFF";
    out.extended = true;
  } else if (id_len <= 3) {
    if (id > 0x7FFu) return "standard id above 0x7FF";
  } else {
    return "expected a 3-digit (standard) or 8-digit (extended) hex id";
  }
  out.id = id;
  ++p;
  int max_len = 8;
  if (p < end && *p == '#') {  // CAN FD: ##<flags nibble><data>
    ++p;
    if (p == end || parse::hex_digit(*p) < 0) return "expected the CAN FD flags nibble after '##'";
    ++p;
    out.fd = true;
    max_len = 64;
  } else if (p < end && (*p == 'R' || *p == 'r')) {
    return "";  // remote frame: no payload to decode (the caller skips it)
  }
  int n = 0;
  while (p < end && parse::hex_digit(p[0]) >= 0) {
    const int hi = parse::hex_digit(p[0]);
    const int lo = p + 1 < end ? parse::hex_digit(p[1]) : -1;
    if (lo < 0) return "odd number of hex digits in the payload";
    if (n == max_len)
      return out.fd ? "payload longer than 64 bytes" : "classic CAN payload longer than 8 bytes";
    out.data[static_cast<std::size_t>(n++)] = static_cast<std::uint8_t>((hi << 4) | lo);
    p += 2;
  }
  if (p < end && parse::hex_digit(*p) >= 0) return "odd number of hex digits in the payload";
  if (out.fd && !valid_fd_len(n)) return "CAN FD payload length not one of 0-8,12,16,20,24,32,48,64";
  out.len = static_cast<std::uint8_t>(n);
  parse::skip_ws(p, end);
  // candump -x direction marker / trailing comment are allowed; anything else is not.
  if (p < end && !((*p == 'T' || *p == 'R') && p + 1 == end)) return "unexpected text after the payload";
  return nullptr;
}

SourceStatus CandumpSource::next(CanFrame& out) noexcept {
  if (!ok_) return SourceStatus::kError;
  auto note_drop = [&](const TimeDrop& d) { note_time_drop(d, path_, stats_, messages_, error_); };
  std::string_view line;
  for (;;) {
    const LineStep step = next_line_or_record(sanity_, reader_, eof_, stats_, out, line, note_drop);
    if (step == LineStep::kRecord) return SourceStatus::kOk;
    if (step == LineStep::kEnd) return finish_lines(reader_, path_, stats_, error_);
    stats_.lines = reader_.line_number();
    if (line.empty() || line.front() == '#') continue;
    std::string_view bus;
    const char* err = parse_line(line, frame_, bus);
    if (err != nullptr) {
      if (*err == '\0') {  // remote frame
        ++rtr_frames_;
        continue;
      }
      ++stats_.bad_lines;
      if (messages_.size() < kMaxMessages) {
        try {
          messages_.push_back(path_ + ":" + std::to_string(reader_.line_number()) + ": " + err + ": '" +
                              std::string(line.substr(0, 80)) + "'");
          error_ = messages_.back();
        } catch (...) {
        }
      }
      continue;
    }
    frame_.bus = bus_index(bus);
    frame_.t_ns += opt_.time_offset_ns;
    stats_.bytes = reader_.bytes();
    sanity_.push(frame_, frame_.t_ns, reader_.line_number());
    sanity_.drain_drops(note_drop);
  }
}

/// Index of an interface name, registered on first sight (more than kMaxBuses share the last index).
std::uint8_t CandumpSource::bus_index(std::string_view bus) noexcept {
  int b = 0;
  while (b < buses_ && std::string_view(bus_names_[static_cast<std::size_t>(b)].data(),
                                        bus_name_len_[static_cast<std::size_t>(b)]) != bus)
    ++b;
  if (b == buses_) {
    if (buses_ < kMaxBuses) {
      bus_name_len_[static_cast<std::size_t>(buses_)] =
          static_cast<std::uint8_t>(std::min(bus.size(), bus_names_[0].size() - 1));
      auto& slot = bus_names_[static_cast<std::size_t>(buses_++)];
      const std::size_t n = std::min(bus.size(), slot.size() - 1);
      std::memcpy(slot.data(), bus.data(), n);
      slot[n] = '\0';
    } else {
      b = kMaxBuses - 1;  // more interfaces than we track: share the last index
    }
  }
  return static_cast<std::uint8_t>(b);
}

}  // namespace torqued

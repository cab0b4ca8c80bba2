#include "mcap_format.hpp"

#include <zlib.h>
#include <zstd.h>

#include <cstring>

namespace torqued::dash::mcap {

std::uint32_t crc32(const void* p, std::size_t n, std::uint32_t crc) {
  // zlib takes uInt lengths: feed large ranges in pieces.
  const auto* b = static_cast<const Bytef*>(p);
  uLong c = crc;
  while (n > 0) {
    const std::size_t k = n > (1u << 30) ? (1u << 30) : n;
    c = ::crc32(c, b, static_cast<uInt>(k));
    b += k;
    n -= k;
  }
  return static_cast<std::uint32_t>(c);
}

void put_str(std::string& out, std::string_view s) {
  put_le<std::uint32_t>(out, static_cast<std::uint32_t>(s.size()));
  out.append(s);
}

std::uint64_t Fields::num(int n) {
  if (!ok_ || b_.size() - pos_ < static_cast<std::size_t>(n)) {
    ok_ = false;
    return 0;
  }
  std::uint64_t v = 0;
  for (int i = 0; i < n; ++i)
    v |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(b_[pos_ + static_cast<std::size_t>(i)]))
         << (8 * i);
  pos_ += static_cast<std::size_t>(n);
  return v;
}

std::string_view Fields::bytes(std::uint64_t n) {
  if (!ok_ || b_.size() - pos_ < n) {
    ok_ = false;
    return {};
  }
  const std::string_view v = b_.substr(pos_, n);
  pos_ += n;
  return v;
}

Split split_records(std::string_view data) {
  Split s;
  std::uint64_t pos = 0;
  while (pos < data.size()) {
    if (data.size() - pos < kRecordHead) break;
    Fields f(data.substr(pos, kRecordHead));
    const std::uint8_t op = f.u8();
    const std::uint64_t len = f.u64();
    if (len > data.size() - pos - kRecordHead) break;
    s.records.push_back({op, pos, data.substr(pos + kRecordHead, len)});
    pos += kRecordHead + len;
  }
  s.end = pos;
  s.truncated = pos < data.size();
  return s;
}

FileView split_file(std::string_view file) {
  FileView v;
  constexpr std::size_t m = sizeof kMagic;
  v.magic = file.size() >= m && std::memcmp(file.data(), kMagic, m) == 0;
  if (!v.magic) return v;
  // A closed file ends with Footer + magic: split only up to the closing magic.
  const bool tail_magic = file.size() >= 2 * m && std::memcmp(file.data() + file.size() - m, kMagic, m) == 0;
  std::string_view body = file.substr(m, tail_magic ? file.size() - 2 * m : std::string_view::npos);
  v.split = split_records(body);
  if (tail_magic && v.split.truncated) v.split = split_records(file.substr(m));  // magic bytes were data
  for (auto& r : v.split.records) r.offset += m;
  v.split.end += m;
  v.closed = tail_magic && !v.split.truncated && !v.split.records.empty() &&
             v.split.records.back().op == kFooter && v.split.end + m == file.size();
  return v;
}

std::optional<MessageView> parse_message(std::string_view body) {
  Fields f(body);
  MessageView m;
  m.channel = f.u16();
  m.sequence = f.u32();
  m.log_time = f.u64();
  m.publish_time = f.u64();
  if (!f.ok()) return std::nullopt;
  m.data = f.rest();
  return m;
}

std::optional<ChunkView> parse_chunk(std::string_view body) {
  Fields f(body);
  ChunkView c;
  c.start_time = f.u64();
  c.end_time = f.u64();
  c.uncompressed_size = f.u64();
  c.uncompressed_crc = f.u32();
  c.compression = f.str();
  c.records = f.bytes(f.u64());
  if (!f.ok()) return std::nullopt;
  return c;
}

std::string decompress_chunk(const ChunkView& c, std::string& out) {
  if (c.uncompressed_size > (std::uint64_t{1} << 32)) return "chunk larger than 4 GiB (corrupt size field?)";
  out.resize(c.uncompressed_size);
  if (c.compression.empty()) {
    if (c.records.size() != c.uncompressed_size) return "uncompressed chunk size mismatch";
    out.assign(c.records);
  } else if (c.compression == "zstd") {
    const std::size_t n = ZSTD_decompress(out.data(), out.size(), c.records.data(), c.records.size());
    if (ZSTD_isError(n)) return std::string("zstd: ") + ZSTD_getErrorName(n);
    if (n != c.uncompressed_size) return "zstd chunk: uncompressed size mismatch";
  } else {
    return "unsupported chunk compression '" + std::string(c.compression) + "'";
  }
  if (c.uncompressed_crc != 0 && crc32(out.data(), out.size()) != c.uncompressed_crc)
    return "chunk CRC mismatch";
  return "";
}

}  // namespace torqued::dash::mcap

#include "mcap_writer.hpp"

#include <cerrno>
#include <cstring>

#include "foxglove.hpp"

namespace torqued::dash {
namespace {

constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};
enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kStatistics = 0x0B,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F
};

template <class T>
void le(std::string& out, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i)
    out += static_cast<char>(static_cast<std::uint64_t>(v) >> (8 * i));
}
void str(std::string& out, std::string_view s) {
  le<std::uint32_t>(out, static_cast<std::uint32_t>(s.size()));
  out.append(s);
}

}  // namespace

McapWriter::McapWriter(const std::string& path, const dds::DdsSettings& settings) : settings_(settings) {
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) {
    error_ = "cannot create " + path + ": " + std::strerror(errno);
    return;
  }
  std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
  put(kMagic, sizeof kMagic);
  std::string h;
  str(h, "");  // profile: none (JSON messages, not a ROS profile)
  str(h, "torque-dash (torqued)");
  record(kHeader, h);
  for (int i = 0; i < dds::kTopicCount; ++i) record(kSchema, schema_record(i));
  for (int i = 0; i < dds::kTopicCount; ++i) record(kChannel, channel_record(i));
}

McapWriter::~McapWriter() { close(); }

std::string McapWriter::schema_record(int i) const {
  const auto t = static_cast<dds::Topic>(i);
  std::string b;
  le<std::uint16_t>(b, static_cast<std::uint16_t>(foxglove::channel_id(t)));  // schema id = channel id
  str(b, foxglove::schema_name(t));
  str(b, "jsonschema");
  str(b, foxglove::json_schema(t));
  return b;
}

std::string McapWriter::channel_record(int i) const {
  const auto t = static_cast<dds::Topic>(i);
  std::string b;
  le<std::uint16_t>(b, static_cast<std::uint16_t>(foxglove::channel_id(t)));
  le<std::uint16_t>(b, static_cast<std::uint16_t>(foxglove::channel_id(t)));
  str(b, foxglove::channel_topic(settings_, t));
  str(b, "json");
  std::string meta;  // map<string,string>: the DDS type name
  str(meta, "dds_type");
  str(meta, "torque::" + std::string(dds::kTopicNames[i]));
  le<std::uint32_t>(b, static_cast<std::uint32_t>(meta.size()));
  b += meta;
  return b;
}

std::string McapWriter::statistics_record() const {
  std::string b;
  le<std::uint64_t>(b, messages_);
  le<std::uint16_t>(b, dds::kTopicCount);  // schemas
  le<std::uint32_t>(b, dds::kTopicCount);  // channels
  le<std::uint32_t>(b, 0);                 // attachments
  le<std::uint32_t>(b, 0);                 // metadata
  le<std::uint32_t>(b, 0);                 // chunks
  le<std::uint64_t>(b, start_ns_);
  le<std::uint64_t>(b, end_ns_);
  std::string counts;
  for (int i = 0; i < dds::kTopicCount; ++i) {
    le<std::uint16_t>(counts, static_cast<std::uint16_t>(i + 1));
    le<std::uint64_t>(counts, per_channel_[static_cast<std::size_t>(i)]);
  }
  le<std::uint32_t>(b, static_cast<std::uint32_t>(counts.size()));
  b += counts;
  return b;
}

void McapWriter::put(const void* p, std::size_t n) {
  if (!f_ || !error_.empty()) return;
  if (std::fwrite(p, 1, n, f_) != n) {
    error_ = std::string("MCAP write failed: ") + std::strerror(errno);
    return;
  }
  offset_ += n;
}

void McapWriter::record(std::uint8_t opcode, const std::string& body) {
  char head[9];
  head[0] = static_cast<char>(opcode);
  const std::uint64_t n = body.size();
  for (int i = 0; i < 8; ++i) head[1 + i] = static_cast<char>(n >> (8 * i));
  put(head, sizeof head);
  put(body.data(), body.size());
}

void McapWriter::write(const dds::AnySample& s, std::uint64_t receive_time_ns) {
  if (!f_ || !error_.empty()) return;
  const auto ch = static_cast<std::size_t>(s.topic);
  const auto publish =
      s.visit([](const auto& v) { return v.publish_t_ns != 0 ? v.publish_t_ns : v.source_t_ns; });
  scratch_.clear();
  le<std::uint16_t>(scratch_, static_cast<std::uint16_t>(foxglove::channel_id(s.topic)));
  le<std::uint32_t>(scratch_, ++seq_[ch]);
  le<std::uint64_t>(scratch_, receive_time_ns);
  le<std::uint64_t>(scratch_, static_cast<std::uint64_t>(publish));
  scratch_ += foxglove::sample_json(s);
  record(kMessage, scratch_);
  if (messages_ == 0 || receive_time_ns < start_ns_) start_ns_ = receive_time_ns;
  if (receive_time_ns > end_ns_) end_ns_ = receive_time_ns;
  ++messages_;
  ++per_channel_[ch];
}

void McapWriter::close() {
  if (!f_) return;
  std::string crc;
  le<std::uint32_t>(crc, 0);
  record(kDataEnd, crc);
  // Summary: schemas, channels, statistics; then one summary offset per group.
  const std::uint64_t summary_start = offset_;
  struct Group {
    std::uint8_t op;
    std::uint64_t start, length;
  };
  Group groups[3] = {{kSchema, offset_, 0}, {kChannel, 0, 0}, {kStatistics, 0, 0}};
  for (int i = 0; i < dds::kTopicCount; ++i) record(kSchema, schema_record(i));
  groups[0].length = offset_ - groups[0].start;
  groups[1].start = offset_;
  for (int i = 0; i < dds::kTopicCount; ++i) record(kChannel, channel_record(i));
  groups[1].length = offset_ - groups[1].start;
  groups[2].start = offset_;
  record(kStatistics, statistics_record());
  groups[2].length = offset_ - groups[2].start;
  const std::uint64_t offsets_start = offset_;
  for (const Group& g : groups) {
    std::string b;
    le<std::uint8_t>(b, g.op);
    le<std::uint64_t>(b, g.start);
    le<std::uint64_t>(b, g.length);
    record(kSummaryOffset, b);
  }
  std::string footer;
  le<std::uint64_t>(footer, summary_start);
  le<std::uint64_t>(footer, offsets_start);
  le<std::uint32_t>(footer, 0);
  record(kFooter, footer);
  put(kMagic, sizeof kMagic);
  if (std::fclose(f_) != 0 && error_.empty())
    error_ = std::string("MCAP close failed: ") + std::strerror(errno);
  f_ = nullptr;
}

}  // namespace torqued::dash

#include "mcap_writer.hpp"

#include <time.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "foxglove.hpp"
#include "mcap_format.hpp"

namespace torqued::dash {

using mcap::put_le;
using mcap::put_str;

namespace {
std::uint64_t thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000'000ull + static_cast<std::uint64_t>(ts.tv_nsec);
}
}  // namespace

McapWriter::McapWriter(const std::string& path, McapOptions opt) : opt_(std::move(opt)) {
  if (opt_.compression != "zstd" && !opt_.compression.empty()) {
    error_ = "MCAP compression '" + opt_.compression + "' not supported (zstd or none)";
    return;
  }
  if (opt_.compression == "zstd" && (zstd_ = ZSTD_createCCtx()) == nullptr) {
    error_ = "MCAP: cannot create a zstd context";
    return;
  }
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) {
    error_ = "cannot create " + path + ": " + std::strerror(errno);
    return;
  }
  std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
  put(mcap::kMagic, sizeof mcap::kMagic);
  std::string h;
  put_str(h, "");  // profile: none (JSON messages, not a ROS profile)
  put_str(h, opt_.library);
  record(mcap::kHeader, h);
}

McapWriter::McapWriter(const std::string& path, const dds::DdsSettings& settings, McapOptions opt)
    : McapWriter(path, [&] {
        opt.library = "torque-dash (torqued)";
        return std::move(opt);
      }()) {
  for (int i = 0; i < dds::kTopicCount; ++i) {
    const auto t = static_cast<dds::Topic>(i);
    const auto id = static_cast<std::uint16_t>(foxglove::channel_id(t));  // schema id = channel id
    add_schema(id, foxglove::schema_name(t), "jsonschema", foxglove::json_schema(t));
    add_channel(id, id, foxglove::channel_topic(settings, t), "json",
                {{"dds_type", "torque::" + std::string(dds::kTopicNames[i])}});
  }
  if (f_ && std::fflush(f_) != 0 && error_.empty()) error_ = std::string("MCAP: ") + std::strerror(errno);
}

McapWriter::~McapWriter() {
  close();
  ZSTD_freeCCtx(zstd_);
}

void McapWriter::add_schema(std::uint16_t id, std::string_view name, std::string_view encoding,
                            std::string_view data) {
  std::string b;
  put_le<std::uint16_t>(b, id);
  put_str(b, name);
  put_str(b, encoding);
  put_str(b, data);
  record(mcap::kSchema, b);
  schemas_.push_back(std::move(b));
}

void McapWriter::add_channel(std::uint16_t id, std::uint16_t schema_id, std::string_view topic,
                             std::string_view encoding,
                             const std::vector<std::pair<std::string, std::string>>& metadata) {
  std::string b;
  put_le<std::uint16_t>(b, id);
  put_le<std::uint16_t>(b, schema_id);
  put_str(b, topic);
  put_str(b, encoding);
  std::string meta;  // map<string,string>
  for (const auto& [k, v] : metadata) {
    put_str(meta, k);
    put_str(meta, v);
  }
  put_str(b, meta);
  record(mcap::kChannel, b);
  channels_.push_back(std::move(b));
}

McapWriter::ChannelIndex& McapWriter::index_of(std::uint16_t channel) {
  for (auto& c : chunk_channels_)
    if (c.id == channel) return c;
  chunk_channels_.push_back({channel, {}});
  return chunk_channels_.back();
}

void McapWriter::write_message(std::uint16_t channel, std::uint32_t sequence, std::uint64_t log_time,
                               std::uint64_t publish_time, std::string_view data) {
  if (!f_ || !error_.empty()) return;
  if (!chunk_.empty() && log_time >= chunk_start_ns_ + opt_.chunk_period_ns) flush_chunk();
  if (chunk_.empty()) chunk_start_ns_ = chunk_end_ns_ = log_time;
  index_of(channel).entries.emplace_back(log_time, chunk_.size());
  put_le<std::uint8_t>(chunk_, mcap::kMessage);
  put_le<std::uint64_t>(chunk_, 2 + 4 + 8 + 8 + data.size());
  put_le<std::uint16_t>(chunk_, channel);
  put_le<std::uint32_t>(chunk_, sequence);
  put_le<std::uint64_t>(chunk_, log_time);
  put_le<std::uint64_t>(chunk_, publish_time);
  chunk_.append(data);
  chunk_start_ns_ = std::min(chunk_start_ns_, log_time);
  chunk_end_ns_ = std::max(chunk_end_ns_, log_time);
  if (messages_ == 0 || log_time < start_ns_) start_ns_ = log_time;
  end_ns_ = std::max(end_ns_, log_time);
  ++messages_;
  auto it =
      std::find_if(per_channel_.begin(), per_channel_.end(), [&](auto& p) { return p.first == channel; });
  if (it == per_channel_.end())
    per_channel_.emplace_back(channel, 1);
  else
    ++it->second;
  if (chunk_.size() >= opt_.chunk_bytes) flush_chunk();
}

void McapWriter::write(const dds::AnySample& s, std::uint64_t receive_time_ns) {
  const auto ch = static_cast<std::size_t>(s.topic);
  const auto publish =
      s.visit([](const auto& v) { return v.publish_t_ns != 0 ? v.publish_t_ns : v.source_t_ns; });
  scratch_ = foxglove::sample_json(s);
  write_message(static_cast<std::uint16_t>(foxglove::channel_id(s.topic)), ++seq_[ch], receive_time_ns,
                static_cast<std::uint64_t>(publish), scratch_);
}

void McapWriter::tick(std::uint64_t now_ns) {
  if (!chunk_.empty() && now_ns >= chunk_start_ns_ + opt_.chunk_period_ns) flush_chunk();
}

void McapWriter::flush_chunk() {
  if (chunk_.empty() || !f_ || !error_.empty()) return;
  const std::uint64_t cpu0 = thread_cpu_ns();
  std::string_view packed = chunk_;
  if (zstd_) {
    packed_.resize(ZSTD_compressBound(chunk_.size()));
    const std::size_t n = ZSTD_compressCCtx(zstd_, packed_.data(), packed_.size(), chunk_.data(),
                                            chunk_.size(), opt_.zstd_level);
    if (ZSTD_isError(n)) {
      error_ = std::string("MCAP: zstd: ") + ZSTD_getErrorName(n);
      return;
    }
    packed = std::string_view(packed_.data(), n);
  }
  // Chunk record: fields, then the (compressed) records, written without copying them into the body.
  std::string head;
  put_le<std::uint64_t>(head, chunk_start_ns_);
  put_le<std::uint64_t>(head, chunk_end_ns_);
  put_le<std::uint64_t>(head, chunk_.size());
  put_le<std::uint32_t>(head, mcap::crc32(chunk_.data(), chunk_.size()));
  put_str(head, opt_.compression);
  put_le<std::uint64_t>(head, packed.size());
  const std::uint64_t chunk_start = offset_;
  std::string op;
  put_le<std::uint8_t>(op, mcap::kChunk);
  put_le<std::uint64_t>(op, head.size() + packed.size());
  put(op.data(), op.size());
  put(head.data(), head.size());
  put(packed.data(), packed.size());
  const std::uint64_t chunk_length = offset_ - chunk_start;
  // One MessageIndex per channel, by channel id, entries by log time.
  std::sort(chunk_channels_.begin(), chunk_channels_.end(), [](auto& a, auto& b) { return a.id < b.id; });
  std::string offsets, b;
  const std::uint64_t index_start = offset_;
  for (auto& c : chunk_channels_) {
    std::stable_sort(c.entries.begin(), c.entries.end(), [](auto& x, auto& y) { return x.first < y.first; });
    put_le<std::uint16_t>(offsets, c.id);
    put_le<std::uint64_t>(offsets, offset_);
    b.clear();
    put_le<std::uint16_t>(b, c.id);
    put_le<std::uint32_t>(b, static_cast<std::uint32_t>(c.entries.size() * 16));
    for (const auto& [t, o] : c.entries) {
      put_le<std::uint64_t>(b, t);
      put_le<std::uint64_t>(b, o);
    }
    record(mcap::kMessageIndex, b);
  }
  std::string ci;
  put_le<std::uint64_t>(ci, chunk_start_ns_);
  put_le<std::uint64_t>(ci, chunk_end_ns_);
  put_le<std::uint64_t>(ci, chunk_start);
  put_le<std::uint64_t>(ci, chunk_length);
  put_str(ci, offsets);
  put_le<std::uint64_t>(ci, offset_ - index_start);
  put_str(ci, opt_.compression);
  put_le<std::uint64_t>(ci, packed.size());
  put_le<std::uint64_t>(ci, chunk_.size());
  chunk_index_.push_back(std::move(ci));
  chunk_.clear();
  chunk_channels_.clear();
  // Flushed: a kill -9 after this point keeps the chunk (the page cache holds it).
  if (std::fflush(f_) != 0 && error_.empty())
    error_ = std::string("MCAP write failed: ") + std::strerror(errno);
  chunk_cpu_ns_ += thread_cpu_ns() - cpu0;
}

void McapWriter::close() {
  if (!f_) return;
  flush_chunk();
  std::string crc;
  put_le<std::uint32_t>(crc, crc_);
  record(mcap::kDataEnd, crc);
  write_summary();
  put(mcap::kMagic, sizeof mcap::kMagic);
  if (std::fclose(f_) != 0 && error_.empty())
    error_ = std::string("MCAP close failed: ") + std::strerror(errno);
  f_ = nullptr;
}

void McapWriter::write_summary() {
  const std::uint64_t summary_start = offset_;
  crc_ = 0;  // from here on: the summary CRC
  struct Group {
    std::uint8_t op;
    std::uint64_t start, length;
  };
  std::vector<Group> groups;
  auto group = [&](std::uint8_t op, const std::vector<std::string>& bodies) {
    if (bodies.empty()) return;
    const std::uint64_t start = offset_;
    for (const auto& b : bodies) record(op, b);
    groups.push_back({op, start, offset_ - start});
  };
  group(mcap::kSchema, schemas_);
  group(mcap::kChannel, channels_);
  std::string st;
  put_le<std::uint64_t>(st, messages_);
  put_le<std::uint16_t>(st, static_cast<std::uint16_t>(schemas_.size()));
  put_le<std::uint32_t>(st, static_cast<std::uint32_t>(channels_.size()));
  put_le<std::uint32_t>(st, 0);  // attachments
  put_le<std::uint32_t>(st, 0);  // metadata
  put_le<std::uint32_t>(st, static_cast<std::uint32_t>(chunk_index_.size()));
  put_le<std::uint64_t>(st, start_ns_);
  put_le<std::uint64_t>(st, end_ns_);
  std::string counts;
  auto sorted = per_channel_;
  std::sort(sorted.begin(), sorted.end());
  for (const auto& [id, n] : sorted) {
    put_le<std::uint16_t>(counts, id);
    put_le<std::uint64_t>(counts, n);
  }
  put_str(st, counts);
  group(mcap::kStatistics, {st});
  group(mcap::kChunkIndex, chunk_index_);
  const std::uint64_t offsets_start = offset_;
  for (const Group& g : groups) {
    std::string b;
    put_le<std::uint8_t>(b, g.op);
    put_le<std::uint64_t>(b, g.start);
    put_le<std::uint64_t>(b, g.length);
    record(mcap::kSummaryOffset, b);
  }
  // Footer: its summary CRC covers the summary and summary offset sections and the footer's first fields.
  std::string footer;
  put_le<std::uint8_t>(footer, mcap::kFooter);
  put_le<std::uint64_t>(footer, 8 + 8 + 4);
  put_le<std::uint64_t>(footer, summary_start);
  put_le<std::uint64_t>(footer, offsets_start);
  put(footer.data(), footer.size());
  std::string crc;
  put_le<std::uint32_t>(crc, crc_);
  put(crc.data(), crc.size());
}

void McapWriter::put(const void* p, std::size_t n) {
  if (!f_ || !error_.empty()) return;
  if (std::fwrite(p, 1, n, f_) != n) {
    error_ = std::string("MCAP write failed: ") + std::strerror(errno);
    return;
  }
  crc_ = mcap::crc32(p, n, crc_);
  offset_ += n;
}

void McapWriter::record(std::uint8_t opcode, std::string_view body) {
  char head[mcap::kRecordHead];
  head[0] = static_cast<char>(opcode);
  const std::uint64_t n = body.size();
  for (int i = 0; i < 8; ++i) head[1 + i] = static_cast<char>(n >> (8 * i));
  put(head, sizeof head);
  put(body.data(), body.size());
}

}  // namespace torqued::dash

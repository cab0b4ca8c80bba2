#include "mcap_recover.hpp"

#include <fstream>
#include <iterator>
#include <set>
#include <utility>
#include <vector>

#include "mcap_format.hpp"

namespace torqued::dash {
namespace {

struct Copier {
  McapWriter& out;
  RecoverResult& r;
  std::set<std::uint16_t> schemas, channels;

  void schema(std::string_view body) {
    mcap::Fields f(body);
    const std::uint16_t id = f.u16();
    const auto name = f.str(), encoding = f.str(), data = f.str();
    if (!f.ok() || id == 0 || !schemas.insert(id).second) return;  // repeated in chunks/summary: first one
    out.add_schema(id, name, encoding, data);
    ++r.schemas;
  }
  void channel(std::string_view body) {
    mcap::Fields f(body);
    const std::uint16_t id = f.u16(), schema_id = f.u16();
    const auto topic = f.str(), encoding = f.str();
    mcap::Fields meta(f.str());
    if (!f.ok() || !channels.insert(id).second) return;
    std::vector<std::pair<std::string, std::string>> m;
    while (meta.ok() && meta.remaining() > 0) {
      const auto k = meta.str(), v = meta.str();
      if (meta.ok()) m.emplace_back(std::string(k), std::string(v));
    }
    out.add_channel(id, schema_id, topic, encoding, m);
    ++r.channels;
  }
  void message(std::string_view body) {
    const auto m = mcap::parse_message(body);
    if (!m || !channels.count(m->channel)) return;  // a message before its channel: not readable either
    out.write_message(m->channel, m->sequence, m->log_time, m->publish_time, m->data);
    ++r.messages;
  }
  /// Returns false at DataEnd (the summary only repeats what was read).
  bool top(const mcap::RecordView& rec, std::string& buf) {
    switch (rec.op) {
      case mcap::kSchema:
        schema(rec.body);
        break;
      case mcap::kChannel:
        channel(rec.body);
        break;
      case mcap::kMessage:
        message(rec.body);
        break;
      case mcap::kChunk:
        chunk(rec.body, buf);
        break;
      case mcap::kDataEnd:
        return false;
      default:
        break;  // header, indexes, attachments, metadata: not carried over
    }
    return true;
  }
  void chunk(std::string_view body, std::string& buf) {
    ++r.chunks_read;
    const auto c = mcap::parse_chunk(body);
    if (!c || !mcap::decompress_chunk(*c, buf).empty()) {
      ++r.chunks_bad;
      return;
    }
    const mcap::Split inner = mcap::split_records(buf);
    for (const auto& rec : inner.records) {
      if (rec.op == mcap::kSchema)
        schema(rec.body);
      else if (rec.op == mcap::kChannel)
        channel(rec.body);
      else if (rec.op == mcap::kMessage)
        message(rec.body);
    }
  }
};

}  // namespace

RecoverResult recover_mcap(const std::string& in_path, const std::string& out_path, const McapOptions& opt) {
  RecoverResult r;
  std::ifstream in(in_path, std::ios::binary);
  if (!in) {
    r.error = "cannot read " + in_path;
    return r;
  }
  const std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  r.input_bytes = file.size();
  const mcap::FileView v = mcap::split_file(file);
  if (!v.magic) {
    r.error = in_path + " is not an MCAP file (no MCAP magic)";
    return r;
  }
  r.input_closed = v.closed;
  r.bytes_dropped = v.closed ? 0 : file.size() - v.split.end;
  McapWriter out(out_path, opt);
  Copier c{out, r, {}, {}};
  std::string buf;
  for (const auto& rec : v.split.records)
    if (!c.top(rec, buf)) break;
  out.close();
  if (!out.ok()) r.error = out.error();
  return r;
}

}  // namespace torqued::dash

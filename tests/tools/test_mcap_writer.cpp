// MCAP recording (tools/dash/mcap_writer.hpp): a written file parsed back record by record against the spec's
// layout (https://mcap.dev/spec): CRCs recomputed here with a bitwise CRC-32 of our own (data section,
// summary, every chunk), every chunk decompressed, every message index entry pointing at its message, every
// chunk index at its chunk and message indexes, the statistics counting what was written; a chunk closed by
// tick() is on disk before close(); a file cut anywhere (kill -9) keeps every complete chunk and
// torque-mcap-recover's function rewrites it whole; the independent reader (@mcap/core, indexed and streamed)
// when node is there.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "dash/mcap_format.hpp"
#include "dash/mcap_recover.hpp"
#include "dash/mcap_writer.hpp"

namespace torqued::dash {
namespace {

namespace fs = std::filesystem;

std::uint32_t ref_crc32(std::string_view s) {  // CRC-32/ISO-HDLC, bit by bit
  std::uint32_t c = 0xFFFFFFFFu;
  for (const char ch : s) {
    c ^= static_cast<std::uint8_t>(ch);
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

fs::path tmp_path(const std::string& name) {
  return fs::temp_directory_path() / ("test_mcap_" + std::to_string(::getpid()) + "_" + name);
}

constexpr std::uint64_t kT0 = 1'700'000'000'000'000'000ull, kMs = 1'000'000ull;
constexpr int kMessages = 3000;  // 3 channels, one message per ms: 3 s of log time

/// 3 s of messages on 3 channels with 0.5 s chunks: 6 chunks.
McapWriter& fill(McapWriter& w, int n = kMessages) {
  for (std::uint16_t id = 1; id <= 3; ++id) {
    const std::string n = std::to_string(id);  // (not "s" + n: GCC 12's -Wrestrict false positive)
    w.add_schema(id, std::string("s").append(n), "jsonschema", R"({"type":"object"})");
    w.add_channel(id, id, std::string("/t").append(n), "json", {{"k", "v"}});
  }
  std::uint32_t seq[4] = {};
  for (int i = 0; i < n; ++i) {
    const auto ch = static_cast<std::uint16_t>(1 + i % 3);
    const std::string data = R"({"i":)" + std::to_string(i) + R"(,"x":)" + std::to_string(i * 0.25) + "}";
    w.write_message(ch, ++seq[ch], kT0 + static_cast<std::uint64_t>(i) * kMs, kT0, data);
  }
  return w;
}

struct Parsed {
  std::map<std::uint8_t, int> ops;
  std::uint64_t chunk_messages = 0;
};

/// Every chunk: its CRC, its messages, and the message index records after it (checked against its records).
void check_chunk(std::string_view file, const mcap::RecordView& rec,
                 const std::vector<mcap::RecordView>& after, Parsed& p) {
  const auto c = mcap::parse_chunk(rec.body);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->compression, "zstd");
  std::string raw;
  ASSERT_EQ(mcap::decompress_chunk(*c, raw), "");
  EXPECT_EQ(ref_crc32(raw), c->uncompressed_crc);
  EXPECT_LE(c->end_time - c->start_time, 500 * kMs);
  std::map<std::uint64_t, mcap::MessageView> by_offset;
  for (const auto& r : mcap::split_records(raw).records) {
    ASSERT_EQ(r.op, mcap::kMessage);
    by_offset[r.offset] = *mcap::parse_message(r.body);
  }
  p.chunk_messages += by_offset.size();
  std::size_t indexed = 0;
  for (const auto& mi : after) {
    if (mi.op != mcap::kMessageIndex) break;
    mcap::Fields f(mi.body);
    const std::uint16_t ch = f.u16();
    mcap::Fields e(f.str());
    for (std::uint64_t prev = 0; e.remaining() > 0; ++indexed) {
      const std::uint64_t t = e.u64(), off = e.u64();
      ASSERT_TRUE(by_offset.count(off)) << "index entry at no message";
      EXPECT_EQ(by_offset[off].channel, ch);
      EXPECT_EQ(by_offset[off].log_time, t);
      EXPECT_GE(t, prev);
      prev = t;
    }
  }
  EXPECT_EQ(indexed, by_offset.size());
  (void)file;
}

TEST(McapWriter, ChunksIndexesSummaryAndCrcsParseBack) {
  const auto path = tmp_path("full.mcap");
  {
    McapWriter w(path.string());
    fill(w).close();
    ASSERT_TRUE(w.ok()) << w.error();
    EXPECT_EQ(w.chunks(), 6u);
  }
  const std::string file = slurp(path);
  const mcap::FileView v = mcap::split_file(file);
  ASSERT_TRUE(v.magic);
  ASSERT_TRUE(v.closed);
  const auto& recs = v.split.records;
  EXPECT_EQ(recs.front().op, mcap::kHeader);
  Parsed p;
  std::uint64_t data_end = 0;
  for (std::size_t i = 0; i < recs.size(); ++i) {
    ++p.ops[recs[i].op];
    if (recs[i].op == mcap::kChunk)
      check_chunk(file, recs[i], {recs.begin() + static_cast<long>(i) + 1, recs.end()}, p);
    if (recs[i].op == mcap::kDataEnd && data_end == 0) {
      data_end = recs[i].offset;
      mcap::Fields f(recs[i].body);
      EXPECT_EQ(f.u32(), ref_crc32(std::string_view(file).substr(0, data_end))) << "data section CRC";
    }
  }
  EXPECT_EQ(p.ops[mcap::kChunk], 6);
  EXPECT_EQ(p.ops[mcap::kMessageIndex], 18);  // 3 channels in each chunk
  EXPECT_EQ(p.ops[mcap::kChunkIndex], 6);
  EXPECT_EQ(p.ops[mcap::kSchema], 6);   // data section + summary
  EXPECT_EQ(p.ops[mcap::kMessage], 0);  // every message is in a chunk
  EXPECT_EQ(p.chunk_messages, static_cast<std::uint64_t>(kMessages));
  // Footer: offsets and the summary CRC.
  mcap::Fields footer(recs.back().body);
  const std::uint64_t summary_start = footer.u64(), offsets_start = footer.u64();
  const std::uint32_t summary_crc = footer.u32();
  EXPECT_EQ(summary_start, data_end + mcap::kRecordHead + 4);
  EXPECT_EQ(summary_crc, ref_crc32(std::string_view(file).substr(
                             summary_start, recs.back().offset + 9 + 16 - summary_start)));
  // Summary: chunk indexes point at chunks and their message indexes; statistics; summary offsets.
  std::map<std::uint64_t, const mcap::RecordView*> at;
  for (const auto& r : recs) at[r.offset] = &r;
  int offsets = 0;
  for (const auto& r : recs) {
    if (r.offset < summary_start) continue;
    if (r.op == mcap::kChunkIndex) {
      mcap::Fields f(r.body);
      f.u64(), f.u64();
      const std::uint64_t start = f.u64(), length = f.u64();
      ASSERT_TRUE(at.count(start));
      EXPECT_EQ(at[start]->op, mcap::kChunk);
      EXPECT_EQ(mcap::kRecordHead + at[start]->body.size(), length);
      mcap::Fields mi(f.str());
      while (mi.remaining() > 0) {
        mi.u16();
        const std::uint64_t o = mi.u64();
        ASSERT_TRUE(at.count(o));
        EXPECT_EQ(at[o]->op, mcap::kMessageIndex);
      }
      EXPECT_GT(f.u64(), 0u);
      EXPECT_EQ(f.str(), "zstd");
      const std::uint64_t compressed = f.u64(), uncompressed = f.u64();
      EXPECT_EQ(compressed, at[start]->body.size() - (8 + 8 + 8 + 4 + 4 + 4 + 8));
      EXPECT_GT(uncompressed, compressed);
    } else if (r.op == mcap::kStatistics) {
      mcap::Fields f(r.body);
      EXPECT_EQ(f.u64(), static_cast<std::uint64_t>(kMessages));
      EXPECT_EQ(f.u16(), 3);
      EXPECT_EQ(f.u32(), 3u);
      f.u32(), f.u32();
      EXPECT_EQ(f.u32(), 6u);
      EXPECT_EQ(f.u64(), kT0);
      EXPECT_EQ(f.u64(), kT0 + (kMessages - 1) * kMs);
      mcap::Fields counts(f.str());
      for (std::uint16_t id = 1; id <= 3; ++id) {
        EXPECT_EQ(counts.u16(), id);
        EXPECT_EQ(counts.u64(), static_cast<std::uint64_t>(kMessages / 3));
      }
    } else if (r.op == mcap::kSummaryOffset) {
      ++offsets;
      EXPECT_GE(r.offset, offsets_start);
      mcap::Fields f(r.body);
      const std::uint8_t op = f.u8();
      const std::uint64_t start = f.u64();
      ASSERT_TRUE(at.count(start));
      EXPECT_EQ(at[start]->op, op);
    }
  }
  EXPECT_EQ(offsets, 4);  // schemas, channels, statistics, chunk indexes
  fs::remove(path);
}

TEST(McapWriter, TickPutsAnOldChunkOnDiskBeforeClose) {
  const auto path = tmp_path("tick.mcap");
  McapWriter w(path.string());
  fill(w, 100);  // 0.1 s of log time: the chunk stays open
  const auto size0 = fs::file_size(path);
  w.tick(kT0 + 400 * kMs);
  EXPECT_EQ(fs::file_size(path), size0) << "a chunk younger than its period stays in memory";
  w.tick(kT0 + 500 * kMs);
  EXPECT_GT(fs::file_size(path), size0) << "flushed by tick()";
  const mcap::FileView v = mcap::split_file(slurp(path));
  EXPECT_FALSE(v.closed);
  EXPECT_FALSE(v.split.truncated);
  EXPECT_EQ(v.split.records.back().op, mcap::kMessageIndex);
  EXPECT_EQ(w.chunks(), 1u);
  w.close();
  fs::remove(path);
}

TEST(McapWriter, FileCutAnywhereKeepsCompleteChunksAndRecovers) {
  const auto path = tmp_path("whole.mcap"), cut = tmp_path("cut.mcap"), out = tmp_path("recovered.mcap");
  {
    McapWriter w(path.string());
    fill(w).close();
  }
  const std::string file = slurp(path);
  const auto recs = mcap::split_file(file).split.records;
  // Messages in the chunks that end before each cut.
  for (const double frac : {0.05, 0.3, 0.52, 0.77, 0.93}) {
    const auto n = static_cast<std::size_t>(frac * static_cast<double>(file.size()));
    std::ofstream(cut, std::ios::binary).write(file.data(), static_cast<std::streamsize>(n));
    std::uint64_t expect = 0;
    for (const auto& r : recs)
      if (r.op == mcap::kChunk && r.offset + mcap::kRecordHead + r.body.size() <= n) {
        std::string raw;
        ASSERT_EQ(mcap::decompress_chunk(*mcap::parse_chunk(r.body), raw), "");
        expect += mcap::split_records(raw).records.size();
      }
    const RecoverResult res = recover_mcap(cut.string(), out.string());
    ASSERT_EQ(res.error, "");
    EXPECT_FALSE(res.input_closed);
    EXPECT_EQ(res.messages, expect) << "cut at " << n;
    EXPECT_EQ(res.channels, 3u);
    const mcap::FileView rv = mcap::split_file(slurp(out));
    EXPECT_TRUE(rv.closed);
  }
  // A closed file goes through unchanged in content.
  const RecoverResult whole = recover_mcap(path.string(), out.string());
  EXPECT_TRUE(whole.input_closed);
  EXPECT_EQ(whole.messages, static_cast<std::uint64_t>(kMessages));
  EXPECT_EQ(whole.chunks_bad, 0u);
  for (const auto& p : {path, cut, out}) fs::remove(p);
}

/// The MCAP reference reader (npm @mcap/core, zstd through fzstd), when node and the packages are installed.
TEST(McapWriter, ReferenceReaderIndexedAndStreamed) {
  const std::string modules = TORQUED_SOURCE_DIR "/tools/dash/node_modules";
  if (std::system("command -v node >/dev/null 2>&1") != 0 || !fs::exists(modules + "/@mcap/core") ||
      !fs::exists(modules + "/fzstd"))
    GTEST_SKIP()
        << "node or tools/dash/node_modules (@mcap/core, fzstd) missing: tools/scripts/setup-deps.sh";
  const auto path = tmp_path("node.mcap");
  {
    McapWriter w(path.string());
    fill(w).close();
  }
  const std::string cmd = "NODE_PATH=" + modules +
                          " node " TORQUED_SOURCE_DIR "/tests/integration/dash/mcap_read.cjs " +
                          path.string();
  std::FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
  ASSERT_EQ(::pclose(p), 0) << out;
  const auto j = nlohmann::json::parse(out);
  const auto& ix = j["indexed"];
  ASSERT_FALSE(ix.contains("error")) << ix["error"];
  EXPECT_EQ(ix["messages"], kMessages);
  EXPECT_EQ(ix["statistics"], kMessages);
  EXPECT_EQ(ix["chunks"], 6);
  EXPECT_EQ(ix["compression"], nlohmann::json::array({"zstd"}));
  EXPECT_EQ(ix["seqGaps"], 0);
  const auto& st = j["stream"];
  EXPECT_FALSE(st.contains("error")) << st["error"];
  EXPECT_TRUE(st["done"].get<bool>());
  EXPECT_EQ(st["messages"], kMessages);
  EXPECT_EQ(st["records"]["Chunk"], 6);
  fs::remove(path);
}

}  // namespace
}  // namespace torqued::dash

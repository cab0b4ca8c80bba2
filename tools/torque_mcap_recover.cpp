// torque-mcap-recover: rewrites an MCAP recording with chunks, message indexes, summary and CRCs, e.g. one
// that torque-dash --record-mcap left without its summary (kill -9, power loss) or an older unchunked
// recording.
//   torque-mcap-recover run.mcap run-recovered.mcap
// Everything up to the last complete record is kept (torque-dash flushes each chunk: at most the last
// chunk, under 1 s, is lost). See docs/dashboard.md.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <string>

#include "cli_exit.hpp"
#include "dash/mcap_recover.hpp"

int main(int argc, char** argv) {
  std::string in, out;
  torqued::dash::McapOptions opt;
  opt.library = "torque-mcap-recover (torqued)";
  bool no_compression = false;
  CLI::App app{
      "torque-mcap-recover: rewrite an MCAP file (cut short by kill -9, or unchunked) with zstd chunks, "
      "message indexes, a summary and CRCs, so indexed MCAP readers open it"};
  app.add_option("input", in, "the MCAP file to read")->required()->check(CLI::ExistingFile);
  app.add_option("output", out, "the MCAP file to write (not the input)")->required();
  app.add_flag("--no-compression", no_compression, "store chunks uncompressed");
  app.add_option("--zstd-level", opt.zstd_level, "zstd compression level")
      ->check(CLI::Range(1, 19))
      ->capture_default_str();
  double period_s = static_cast<double>(opt.chunk_period_ns) / 1e9;
  app.add_option("--chunk-period", period_s, "log time one chunk spans at most (s)")
      ->check(CLI::Range(0.01, 3600.0))
      ->capture_default_str();
  app.footer(
      "Exit status: 0 written (the summary line tells what was kept and dropped); 1 the input is not MCAP or "
      "the output cannot be written; 2 command-line error (unknown option, bad value, missing file).");
  TORQUED_CLI_PARSE(app, argc, argv);
  if (no_compression) opt.compression.clear();
  opt.chunk_period_ns = static_cast<std::uint64_t>(period_s * 1e9);
  if (in == out) {
    std::fprintf(stderr, "torque-mcap-recover: the output must not be the input\n");
    return 2;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = torqued::dash::recover_mcap(in, out, opt);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!r.error.empty()) {
    std::fprintf(stderr, "torque-mcap-recover: %s\n", r.error.c_str());
    return 1;
  }
  std::printf(
      "torque-mcap-recover: %llu messages, %llu schemas, %llu channels from %llu input bytes (%s; %llu "
      "chunks read, %llu skipped for a bad CRC or compression; %llu bytes of an incomplete last record "
      "dropped) in %.3f s\n",
      static_cast<unsigned long long>(r.messages), static_cast<unsigned long long>(r.schemas),
      static_cast<unsigned long long>(r.channels), static_cast<unsigned long long>(r.input_bytes),
      r.input_closed ? "closed file" : "no footer: cut short", static_cast<unsigned long long>(r.chunks_read),
      static_cast<unsigned long long>(r.chunks_bad), static_cast<unsigned long long>(r.bytes_dropped), s);
  return 0;
}

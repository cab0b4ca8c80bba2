// Throughput of the encoder-over-CAN path (not a ctest; figures go in the report):
//   build-live/tests/io/bench_can_encoder
// BM_Batcher: edges -> frames (what the encoder interface / torque-canreplay encode do).
// BM_EncoderEdgeSource: frames -> EdgeEvents through CanEncoderEdgeSource (unwrap, sequence check), with and
// without receive-clock alignment. Items = edges.
#include <benchmark/benchmark.h>

#include <vector>

#include "can_encoder.hpp"

namespace torqued {
namespace {

std::vector<EdgeEvent> make_edges(std::size_t n) {
  std::vector<EdgeEvent> e(n);
  for (std::size_t k = 0; k < n; ++k) {
    e[k] = {static_cast<std::int64_t>(k) * 83'333 + 17, 0,
            static_cast<std::uint8_t>(k & 1)};  // 6000 rpm, 60-2
  }
  return e;
}

class VectorCan final : public CanSource {
 public:
  explicit VectorCan(const std::vector<CanFrame>& f) : f_(f) {}
  SourceStatus next(CanFrame& out) noexcept override {
    if (i_ == f_.size()) return SourceStatus::kEnd;
    out = f_[i_++];
    return SourceStatus::kOk;
  }
  const SourceStats& stats() const noexcept override { return s_; }
  std::string describe() const override { return "vector"; }

 private:
  const std::vector<CanFrame>& f_;
  std::size_t i_ = 0;
  SourceStats s_;
};

void BM_Batcher(benchmark::State& state) {
  const auto edges = make_edges(1 << 16);
  CanEncoderConfig cfg;
  CanFrame f;
  std::size_t frames = 0;
  for (auto _ : state) {
    can_encoder::Batcher b(cfg, 1'000'000);
    for (const auto& e : edges) frames += b.push(e, f);
    frames += b.flush(f);
    benchmark::DoNotOptimize(f);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * edges.size()));
  benchmark::DoNotOptimize(frames);
}
BENCHMARK(BM_Batcher);

void BM_EncoderEdgeSource(benchmark::State& state) {
  const auto edges = make_edges(1 << 16);
  CanEncoderConfig cfg;
  cfg.align_to_receive_time = state.range(0) != 0;
  std::vector<CanFrame> frames;
  can_encoder::Batcher b(cfg, 1'000'000);
  CanFrame f;
  for (const auto& e : edges) {
    if (b.push(e, f)) frames.push_back(f);
  }
  while (b.flush(f)) frames.push_back(f);
  for (auto& fr : frames) fr.t_ns += 150'000;  // receive latency
  std::size_t n = 0;
  for (auto _ : state) {
    VectorCan can(frames);
    CanEncoderEdgeSource src(can, cfg);
    EdgeEvent e;
    while (src.next(e) == SourceStatus::kOk) ++n;
    benchmark::DoNotOptimize(e);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * edges.size()));
  benchmark::DoNotOptimize(n);
}
BENCHMARK(BM_EncoderEdgeSource)->Arg(0)->Arg(1)->ArgName("align");

}  // namespace
}  // namespace torqued

BENCHMARK_MAIN();

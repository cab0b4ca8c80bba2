#include "backend_factory.hpp"

#include <algorithm>
#include <cmath>

#include "can_encoder.hpp"
#include "candump_source.hpp"
#include "edge_file_source.hpp"
#include "gpio_source.hpp"
#include "socketcan_source.hpp"

namespace torqued {
namespace {

/// CanEncoderEdgeSource plus the CAN source it reads (owned).
class OwningEncoderSource final : public EdgeSource {
 public:
  OwningEncoderSource(std::unique_ptr<CanSource> can, const CanEncoderConfig& cfg)
      : can_(std::move(can)), enc_(*can_, cfg) {}
  SourceStatus next(EdgeEvent& out) noexcept override { return enc_.next(out); }
  [[nodiscard]] const SourceStats& stats() const noexcept override { return enc_.stats(); }
  [[nodiscard]] std::string describe() const override { return enc_.describe() + " via " + can_->describe(); }
  [[nodiscard]] std::string last_error() const override { return enc_.last_error(); }
  void request_stop() noexcept override { enc_.request_stop(); }
  [[nodiscard]] bool ok() const noexcept { return enc_.ok(); }

 private:
  std::unique_ptr<CanSource> can_;
  CanEncoderEdgeSource enc_;
};

void set(std::string* error, std::string what) {
  if (error != nullptr) *error = std::move(what);
}

}  // namespace

CanEncoderConfig can_encoder_config(const Config& config) noexcept {
  const EdgeInputConfig& in = config.inputs.edges;
  CanEncoderConfig e;
  e.id = in.encoder_can_id;
  e.fd = config.inputs.can.fd;
  e.extended = in.encoder_can_id > 0x7FFu;
  e.crank_channel = kCrankChannel;
  e.cam_channel = kCamChannel;
  // Live only: SocketCAN receive times are CLOCK_REALTIME, the encoder's ticks are its own oscillator's.
  e.align_to_receive_time = config.inputs.can.backend == CanBackend::kSocketCan;
  return e;
}

TimeSanityOptions time_sanity_options(const Config& config) noexcept {
  TimeSanityOptions t;
  t.max_jump_ns = static_cast<std::int64_t>(std::llround(config.inputs.max_time_jump_s * 1e9));
  t.rebase_after = static_cast<std::uint32_t>(std::max(1, config.inputs.time_rebase_records));
  return t;
}

std::int64_t can_time_offset_ns(const Config& config) noexcept {
  return static_cast<std::int64_t>(std::llround(config.inputs.can.time_offset_s * 1e9));
}

DecoderParams decoder_params(const Config& config) noexcept {
  DecoderParams p = config.wheel.decoder;
  p.crank_channel = kCrankChannel;
  p.cam_channel = kCamChannel;
  p.cam_rising = config.wheel.cam_rising_edge;
  if (config.wheel.cam_channel.empty()) p.use_cam = false;
  return p;
}

std::unique_ptr<EdgeSource> make_edge_source(const Config& config, std::string* error) {
  const EdgeInputConfig& in = config.inputs.edges;
  switch (in.backend) {
    case EdgeBackend::kFile: {
      if (in.format == EdgeFormat::kCsv) {
        EdgeCsvOptions o;
        o.crank_column = config.wheel.crank_channel;
        o.cam_column = config.wheel.cam_channel;
        o.crank_channel = kCrankChannel;
        o.cam_channel = kCamChannel;
        o.time = time_sanity_options(config);
        auto src = std::make_unique<EdgeCsvSource>(in.path, o);
        if (!src->ok()) {
          set(error, "inputs.edges: " + src->last_error());
          return nullptr;
        }
        return src;
      }
      EdgeListOptions o;
      o.channel = kCrankChannel;
      o.level = config.wheel.geometry.rising_edge ? 1 : 0;
      o.time = time_sanity_options(config);
      auto src = std::make_unique<EdgeListSource>(in.path, o);
      if (!src->ok()) {
        set(error, "inputs.edges: " + src->last_error());
        return nullptr;
      }
      return src;
    }
    case EdgeBackend::kGpio: {
      GpioConfig g;
      g.chip = in.gpio_chip;
      g.crank_line = in.gpio_crank_line;
      g.cam_line = in.gpio_cam_line;
      g.crank_channel = kCrankChannel;
      g.cam_channel = kCamChannel;
      auto src = std::make_unique<GpioEdgeSource>(g);
      if (!src->ok()) {
        set(error, "inputs.edges (gpio): " + src->last_error());
        return nullptr;
      }
      return src;
    }
    case EdgeBackend::kCanEncoder: {
      std::unique_ptr<CanSource> can;
      if (config.inputs.can.backend == CanBackend::kSocketCan) {
        SocketCanConfig c;
        c.interface = config.inputs.can.interface;
        c.fd = config.inputs.can.fd;
        c.filters.push_back(
            CanIdFilter{in.encoder_can_id & 0x1FFFFFFFu, 0x1FFFFFFFu, in.encoder_can_id > 0x7FFu});
        auto sock = std::make_unique<SocketCanSource>(c);
        if (!sock->ok()) {
          set(error, "inputs.edges (can_encoder): " + sock->last_error());
          return nullptr;
        }
        can = std::move(sock);
      } else {
        CandumpOptions co;
        co.time = time_sanity_options(config);
        auto file = std::make_unique<CandumpSource>(config.inputs.can.path, co);
        if (!file->ok()) {
          set(error, "inputs.edges (can_encoder): " + file->last_error());
          return nullptr;
        }
        can = std::move(file);
      }
      auto src = std::make_unique<OwningEncoderSource>(std::move(can), can_encoder_config(config));
      if (!src->ok()) {
        set(error, "inputs.edges (can_encoder): " + src->last_error());
        return nullptr;
      }
      return src;
    }
  }
  set(error, "inputs.edges: unknown backend");
  return nullptr;
}

std::unique_ptr<CanSource> make_can_source(const Config& config, std::string* error) {
  const CanInputConfig& in = config.inputs.can;
  if (in.backend == CanBackend::kSocketCan) {
    SocketCanConfig c;
    c.interface = in.interface;
    c.fd = in.fd;
    auto sock = std::make_unique<SocketCanSource>(c);
    if (!sock->ok()) {  // a missing/down interface is not an error here: the source keeps retrying
      set(error, "inputs.can (socketcan): " + sock->last_error());
      return nullptr;
    }
    return sock;
  }
  if (in.path.empty()) return nullptr;
  CandumpOptions co;
  co.time = time_sanity_options(config);
  auto src = std::make_unique<CandumpSource>(in.path, co);
  if (!src->ok()) {
    set(error, "inputs.can: " + src->last_error());
    return nullptr;
  }
  return src;
}

std::optional<DbcDatabase> load_dbc(const Config& config, std::string* error,
                                    std::vector<std::string>* warnings) {
  if (config.can.dbc.empty()) return std::nullopt;
  DbcParseResult r = DbcDatabase::parse_file(config.can.dbc);
  // A bad statement skips itself only: refuse when it took out a signal the configuration maps.
  std::string all;
  for (std::size_t q = 0; q < kCanQuantityCount && r.db; ++q) {
    const SignalMapping& m = config.can.signals[q];
    if (!m.mapped()) continue;
    if (const std::string* e = r.affecting(m.message, m.signal))
      all += (all.empty() ? "" : "\n") + std::string("can.signals.") + std::string(can_quantity_name(q)) +
             ": " + m.message + "." + m.signal + " is unusable: " + *e;
  }
  if (!r.db)
    for (const auto& e : r.errors) all += (all.empty() ? "" : "\n") + e;
  if (!all.empty()) {
    set(error, all);
    return std::nullopt;
  }
  if (warnings) {
    *warnings = std::move(r.errors);  // skipped statements that no mapped signal needs
    warnings->insert(warnings->end(), r.warnings.begin(), r.warnings.end());
  }
  return std::move(r.db);
}

bool bind_signals(const Config& config, SignalStore& store, std::string* error) {
  std::string all;
  for (std::size_t i = 0; i < kCanQuantityCount && i < static_cast<std::size_t>(kQuantityCount); ++i) {
    const SignalMapping& m = config.can.signals[i];
    if (!m.mapped()) continue;
    std::string err;
    if (!store.bind(static_cast<Quantity>(i), m.message, m.signal, std::int64_t{m.timeout_ms} * 1'000'000,
                    &err)) {
      all += (all.empty() ? "" : "\n") + err;
    }
  }
  if (!all.empty()) {
    set(error, all);
    return false;
  }
  return true;
}

}  // namespace torqued

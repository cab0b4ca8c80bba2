#include "cam_check.hpp"

#include <cmath>
#include <cstdio>

#include "backend_factory.hpp"
#include "crank_decoder.hpp"

namespace torqued {
namespace {

/// Distance (deg) from pos to the nearest edge of [start, end) if inside, else -1 (720° cycle, may wrap).
double inside_margin(double pos, double start, double end) {
  pos = std::fmod(pos + 720.0, 720.0);
  const double len = std::fmod(end - start + 720.0, 720.0);
  const double from_start = std::fmod(pos - start + 720.0, 720.0);
  if (from_start >= (len == 0.0 ? 720.0 : len)) return -1.0;
  return std::min(from_start, len - from_start);
}

std::string fmt(const char* f, double a, double b = 0, double c = 0, double d = 0) {
  char buf[400];
  std::snprintf(buf, sizeof buf, f, a, b, c, d);
  return buf;
}

}  // namespace

std::vector<std::string> cam_window_warnings(const Config& config, std::int64_t max_edges,
                                             double margin_deg) {
  std::vector<std::string> out;
  const DecoderParams configured = decoder_params(config);
  if (config.inputs.edges.backend != EdgeBackend::kFile || config.inputs.edges.path.empty() ||
      config.inputs.edges.format != EdgeFormat::kCsv || !configured.use_cam || configured.cam_window_auto)
    return out;
  std::string err;
  auto src = make_edge_source(config, &err);
  if (!src) return out;  // the loader reports unreadable inputs
  DecoderParams p = configured;
  p.cam_window_auto = true;
  CrankDecoder dec(config.wheel.geometry, p);
  if (!dec.valid()) return out;
  EdgeEvent e;
  ToothEvent t;
  for (std::int64_t n = 0;
       n < max_edges && dec.stats().cam_angle_deg < 0.0 && src->next(e) == SourceStatus::kOk; ++n)
    dec.on_edge(e, t);
  const double a = dec.stats().cam_angle_deg;
  const std::string& path = config.inputs.edges.path;
  if (a < 0.0) {
    out.push_back(path + ": no steady cam edge found (synced teeth " +
                  std::to_string(dec.stats().synced_teeth) + ", cam edges " +
                  std::to_string(dec.stats().cam_edges) + "): the cam window is not checked");
    return out;
  }
  const double s = configured.cam_window_start_deg, en = configured.cam_window_end_deg;
  const double m0 = inside_margin(a, s, en), m1 = inside_margin(a + 360.0, s, en);
  if (m0 < 0.0 && m1 < 0.0) {
    out.push_back(
        path + fmt(": the cam edge is at %.1f (or %.1f) deg of the cycle, outside wheel.decoder cam window "
                   "[%.1f, %.1f): every cam edge will be a cam phase error and the phase stays unknown",
                   a, a + 360.0, s, en));
  } else if (m0 >= 0.0 && m1 >= 0.0) {
    out.push_back(path +
                  fmt(": the cam window [%.1f, %.1f) holds the cam edge in both revolutions (%.1f and %.1f "
                      "deg): the phase is ambiguous",
                      s, en, a, a + 360.0));
  } else {
    const double margin = m0 >= 0.0 ? m0 : m1;
    if (margin < margin_deg)
      out.push_back(
          path + fmt(": the cam edge at %.1f deg of the cycle is %.1f deg from an edge of the cam window "
                     "[%.1f, %.1f): timing jitter would flip the phase by 360 deg; centre the window on it",
                     m0 >= 0.0 ? a : a + 360.0, margin, s, en));
  }
  return out;
}

}  // namespace torqued

#include "replay_inputs.hpp"

#include "backend_factory.hpp"
#include "config.hpp"

namespace torqued {

RunInputs open_inputs(const Config& cfg) {
  RunInputs in;
  in.settings = stage_settings_from(cfg);
  in.settings.decoder = decoder_params(cfg);
  in.can_offset_ns = can_time_offset_ns(cfg);
  std::string err;
  in.edges = make_edge_source(cfg, &err);
  if (!in.edges) {
    in.error = "inputs.edges: " + err;
    return in;
  }
  err.clear();
  in.can = make_can_source(cfg, &err);
  if (!in.can && !err.empty()) {
    in.error = "inputs.can: " + err;
    return in;
  }
  err.clear();
  in.dbc = load_dbc(cfg, &err, &in.dbc_warnings);
  if (!in.dbc && !err.empty()) in.error = "can.dbc: " + err;
  return in;
}

}  // namespace torqued

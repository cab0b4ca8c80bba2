#include "replay_inputs.hpp"

#include "backend_factory.hpp"
#include "config.hpp"
#include "stage_settings_from.hpp"

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

namespace {
template <class Source>
void add_problems(const Source* s, const char* kind, const char* records, std::vector<std::string>& out) {
  if (s == nullptr) return;
  std::vector<std::string> m = s->input_messages();
  if (m.empty() && s->stats().records == 0) m.push_back(s->describe() + ": no " + records + " in the input");
  for (auto& line : m) out.push_back(std::string(kind) + ": " + line);
}
}  // namespace

std::vector<std::string> input_problems(const EdgeSource* edges, const CanSource* can) {
  std::vector<std::string> out;
  add_problems(edges, "edges", "edge", out);
  add_problems(can, "can", "frame", out);
  return out;
}

}  // namespace torqued

#include "startup_checks.hpp"

#include "backend_factory.hpp"

namespace torqued {

std::vector<std::string> startup_problems(const Config& cfg) {
  std::vector<std::string> out;
  std::string err;
  const bool file_edges =
      cfg.inputs.edges.backend == EdgeBackend::kFile ||
      (cfg.inputs.edges.backend == EdgeBackend::kCanEncoder && cfg.inputs.can.backend == CanBackend::kFile);
  if (file_edges && !make_edge_source(cfg, &err)) out.push_back(err);
  err.clear();
  if (cfg.inputs.can.backend == CanBackend::kFile && !make_can_source(cfg, &err) && !err.empty())
    out.push_back(err);
  return out;
}

}  // namespace torqued

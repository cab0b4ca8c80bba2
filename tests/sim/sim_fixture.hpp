#pragma once
// Shared, cached simulator runs for the tests in tests/sim (each scenario is simulated once per binary).
#include <functional>
#include <map>
#include <string>

#include "engine_sim.hpp"

namespace torqued::sim::test {

struct Run {
  Scenario scenario;
  SimOutput out;
};

/// Simulates `name` shortened to `duration_s` after applying `tweak`; cached under `key` (default: name).
inline const Run& run(const std::string& name, double duration_s,
                      const std::function<void(Scenario&)>& tweak = {}, const std::string& key = {}) {
  static std::map<std::string, Run> cache;
  const std::string k = (key.empty() ? name : key) + "/" + std::to_string(duration_s);
  auto it = cache.find(k);
  if (it != cache.end()) return it->second;
  Scenario sc = scenario_by_name(name);
  sc.duration_s = duration_s;
  if (tweak) tweak(sc);
  Run r{sc, simulate(sc)};
  return cache.emplace(k, std::move(r)).first->second;
}

}  // namespace torqued::sim::test

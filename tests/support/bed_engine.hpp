#pragma once
// tests/support/bed_engine.hpp: an engine of the unseen-engines bed by name for the bed tests
// (tools/sim/unseen_engines.hpp); a name the bed does not have is a test-setup error, thrown.
#include <stdexcept>
#include <string>

#include "unseen_engines.hpp"

namespace torqued::test {

inline const sim::BedEngine& bed_engine(const std::string& name) {
  const sim::BedEngine* e = sim::unseen_engine(name);
  if (e == nullptr) throw std::invalid_argument("no engine '" + name + "' in the unseen-engines bed");
  return *e;
}

}  // namespace torqued::test

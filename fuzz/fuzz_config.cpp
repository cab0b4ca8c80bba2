// libFuzzer target: YAML configuration loader (schema checks, cross-field checks); files are not required.
#include <string>

#include "config_loader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string yaml(reinterpret_cast<const char*>(data), size);
  torqued::LoadOptions o;
  o.check_files = false;
  (void)torqued::load_config_from_string(yaml, "/tmp/fuzz.yaml", o);
  return 0;
}

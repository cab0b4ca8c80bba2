// config/torqued.example.yaml documents every key of the schema table, commented, at its default, and parses.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <set>
#include <string>

#include "config_loader.hpp"
#include "config_schema.hpp"

namespace torqued {
namespace {

const std::string kExample = std::string(TORQUED_SOURCE_DIR) + "/config/torqued.example.yaml";
constexpr const char* kRegenerate =
    "regenerate: build/service/torqued --print-schema > config/torqued.example.yaml";

void collect(const YAML::Node& n, const std::string& prefix, std::set<std::string>& keys) {
  for (auto it = n.begin(); it != n.end(); ++it) {
    const std::string key = prefix.empty() ? it->first.Scalar() : prefix + "." + it->first.Scalar();
    if (it->second.IsMap())
      collect(it->second, key, keys);
    else
      keys.insert(key);
  }
}

TEST(ExampleYaml, DocumentsEverySchemaKey) {
  const YAML::Node root = YAML::LoadFile(kExample);
  std::set<std::string> keys;
  collect(root, "", keys);
  for (const auto& e : config_schema())
    EXPECT_TRUE(keys.count(e.key)) << "undocumented key " << e.key << "; " << kRegenerate;
  for (const auto& k : keys) EXPECT_NE(find_schema_entry(k), nullptr) << "example has unknown key " << k;
}

TEST(ExampleYaml, EveryKeyHasACommentAbove) {
  std::ifstream in(kExample);
  std::string line, prev;
  int keys = 0;
  while (std::getline(in, line)) {
    const auto first = line.find_first_not_of(' ');
    if (first != std::string::npos && line[first] != '#' && line.back() != ':') {  // a "key: value" line
      ++keys;
      EXPECT_NE(prev.find('#'), std::string::npos) << "no comment above: " << line;
    }
    prev = line;
  }
  EXPECT_EQ(static_cast<std::size_t>(keys), config_schema().size());
}

TEST(ExampleYaml, ParsesAndHoldsTheDefaults) {
  const LoadResult r = load_config(kExample, LoadOptions{false});
  ASSERT_TRUE(r.ok()) << (r.errors.empty() ? "" : r.errors.front());
  const Config defaults;
  for (const auto& e : config_schema())
    EXPECT_EQ(format_config_value(e, e.get(*r.config)), format_config_value(e, e.get(defaults)))
        << e.key << " differs from the default; " << kRegenerate;
}

}  // namespace
}  // namespace torqued

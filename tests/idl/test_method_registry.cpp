// The method registry (idl/methods.hpp) against the wire contract: every METHOD_* constant of idl/torque.idl
// (parsed from the IDL text, so a constant added there without an entry fails here) has the entry of its id,
// named after the constant; the registry has no entry the IDL lacks. (Each entry's id is also checked against
// its constant at compile time, in methods.hpp.)
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>

#include "methods.hpp"

namespace {
using namespace torqued::dds;

std::map<std::string, int> idl_method_constants() {
  std::ifstream f(std::string(TORQUED_SOURCE_DIR) + "/idl/torque.idl");
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string text = ss.str();
  std::map<std::string, int> out;
  const std::regex re(R"(const\s+uint8\s+METHOD_([A-Z0-9_]+)\s*=\s*(\d+)\s*;)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    out[(*it)[1].str()] = std::stoi((*it)[2].str());
  return out;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

TEST(TopicMethodRegistry, CoversEveryIdlMethodConstant) {
  const auto idl = idl_method_constants();
  ASSERT_GE(idl.size(), 11u) << "the parser found too few METHOD_* constants in idl/torque.idl";
  for (const auto& [constant, id] : idl) {
    const MethodInfo* m = method_info(static_cast<std::uint8_t>(id));
    ASSERT_NE(m, nullptr) << "METHOD_" << constant << " = " << id << " has no entry in idl/methods.hpp";
    EXPECT_EQ(m->id, id);
    EXPECT_EQ(std::string(m->name), lower(constant)) << "entry " << id << " is not METHOD_" << constant;
  }
  EXPECT_EQ(static_cast<std::size_t>(kMethodCount), idl.size())
      << "an entry of methods.hpp has no IDL constant";
}

TEST(TopicMethodRegistry, EntriesAreComplete) {
  for (const auto& m : kMethods) {
    EXPECT_FALSE(m.label.empty()) << m.name;
    EXPECT_FALSE(m.reference.empty()) << m.name;
    EXPECT_TRUE(std::filesystem::is_regular_file(std::string(TORQUED_SOURCE_DIR) + "/" + std::string(m.doc)))
        << m.name << ": " << m.doc;
    // Instantaneous values are exactly the angle domain's per-tooth methods (what the dashboard places on
    // the crank angle).
    EXPECT_EQ(m.in_cycle, m.domain == MethodDomain::kAngleInCycle) << m.name;
  }
  EXPECT_EQ(method_count(MethodDomain::kTime), 4);
  EXPECT_EQ(method_count(MethodDomain::kAngleInCycle), 2);
  EXPECT_STREQ(method_name(torque_METHOD_FUSED), "fused");
  EXPECT_STREQ(method_name(200), "?");
  EXPECT_EQ(method_info(kMethodCount), nullptr);
}

}  // namespace

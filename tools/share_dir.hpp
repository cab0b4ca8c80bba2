#pragma once
// Where a tool finds the files it ships with (plot scripts, torque-dash's page): PREFIX/share/torqued, found
// from the executable's own location (PREFIX/bin/TOOL), so no build or install directory is compiled into a
// binary and an installed tree works wherever it is put (the package: /usr/bin -> /usr/share/torqued). The
// build tree has the same layout: CMake copies the files to BUILD/share/torqued (tools/CMakeLists.txt) and
// BUILD/tools/TOOL finds them there. The environment variable TORQUED_SHARE_DIR overrides the directory.
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

namespace torqued::tools {

/// PREFIX/share/torqued for the running executable (or $TORQUED_SHARE_DIR).
[[nodiscard]] inline std::string share_dir() {
  if (const char* env = std::getenv("TORQUED_SHARE_DIR"); env != nullptr && *env != '\0') return env;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "/usr/share/torqued";  // no /proc: the package's place
  return (exe.parent_path().parent_path() / "share" / "torqued").string();
}

/// A file of share_dir() (e.g. "plot_torque.py", "www").
[[nodiscard]] inline std::string share_path(const std::string& name) { return share_dir() + "/" + name; }

}  // namespace torqued::tools

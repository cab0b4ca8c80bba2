#pragma once
// tests/vm/vm_check.hpp: what the checks run inside the qemu VM share (vm_can_check, vm_gpio_check): one
// PASS/FAIL line per check on stdout, the failures counted for the exit status, and `--name value` options.
#include <cstdio>
#include <cstring>
#include <string>

namespace torqued::vm {

/// Failed checks so far: the program's exit status is 0 only when none failed.
inline int& failures() {
  static int n = 0;
  return n;
}

/// One check's verdict, printed at once (the VM's console is read while the check runs).
inline void check(bool ok, const std::string& what) {
  std::printf("%s %s\n", ok ? "PASS" : "FAIL", what.c_str());
  std::fflush(stdout);
  if (!ok) ++failures();
}

/// The value after `name` on the command line, or `def`.
inline std::string arg(int argc, char** argv, const char* name, const char* def) {
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], name) == 0) return argv[i + 1];
  }
  return def;
}

}  // namespace torqued::vm

#pragma once
// Command-line errors of every torque-* tool exit with status 2 (CLI11's own codes, e.g. 105 for a file that
// does not exist, are not documented anywhere a user looks); each tool's --help lists its exit statuses
// (footer).
#include <CLI/CLI.hpp>

/// As CLI11_PARSE, but any parse/validation error (unknown option, bad value, missing file) exits with 2.
#define TORQUED_CLI_PARSE(app, argc, argv) \
  try {                                    \
    (app).parse((argc), (argv));           \
  } catch (const CLI::ParseError& e) {     \
    const int cli_rc = (app).exit(e);      \
    return cli_rc == 0 ? 0 : 2;            \
  }

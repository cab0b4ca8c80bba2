#!/usr/bin/env bash
# The habits CI enforces (tools/scripts/test.sh runs this):
#   1. clang-format (.clang-format) on every C++ file of the tree: any file that differs fails, named.
#   2. clang-tidy (.clang-tidy: bug and performance checks, warnings are errors) on the .cpp files changed since
#      BASE (default: the previous commit, HEAD~1; TORQUED_LINT_BASE=<rev> to widen), with the build's
#      compile_commands.json (BUILD_DIR, default build).
# Usage: tools/scripts/lint.sh [BUILD_DIR]      Exit: 0 clean, 1 a file failed a check, 2 a tool is missing.
# Fix the layout with: git ls-files '*.cpp' '*.hpp' | xargs clang-format -i
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
for t in clang-format clang-tidy; do command -v "$t" >/dev/null || { echo "lint: $t not installed"; exit 2; }; done
status=0
mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h' | grep -v '^tests/data/')
bad=()
for f in "${files[@]}"; do clang-format --dry-run -Werror "$f" >/dev/null 2>&1 || bad+=("$f"); done
if ((${#bad[@]})); then
  echo "lint: ${#bad[@]} file(s) differ from clang-format: ${bad[*]}"; status=1
else
  echo "lint: clang-format clean (${#files[@]} files)"
fi
base=${TORQUED_LINT_BASE:-HEAD~1}
if git rev-parse -q --verify "$base" >/dev/null; then
  mapfile -t changed < <(git diff --name-only --diff-filter=AMR "$base" -- '*.cpp' | grep -v '^tests/data/' || true)
else
  changed=()
fi
tidy_one() {  # file: prints the findings and fails when clang-tidy does
  local out
  if ! out=$(clang-tidy -p "$build" --quiet "$1" 2>/dev/null); then
    echo "$out" | grep -E "error:|warning:" | head -20; echo "lint: clang-tidy failed on $1"; return 1
  fi
}
export -f tidy_one; export build
todo=()
for f in "${changed[@]}"; do
  [[ -f "$f" ]] || continue
  grep -q "\"file\": \".*/$f\"" "$build/compile_commands.json" 2>/dev/null && todo+=("$f")  # not built here: skip
done
tidy_fail=0
if ((${#todo[@]})); then
  printf '%s\n' "${todo[@]}" | xargs -P"$(nproc)" -I{} bash -c 'tidy_one "$1"' _ {} || tidy_fail=1
fi
if ((tidy_fail)); then status=1; else echo "lint: clang-tidy clean on ${#todo[@]} changed file(s) since $base"; fi
exit $status

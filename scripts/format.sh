#!/usr/bin/env bash
# Apply every mechanical fix `make lint` asks for: ruff's safe fixes (import order,
# unused imports, ...), ruff format, and clang-format on qogi's own C++.
# What remains after it (`make lint`) needs a person: undefined names, loop-variable
# closures, type errors.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=.venv/bin
[ -x "$bin/ruff" ] && [ -x "$bin/clang-format" ] || make setup
"$bin/ruff" check --fix --quiet . || true   # fixes what it can; the rest is reported by make lint
"$bin/ruff" format .
find cpp examples/cpp_consumer \( -name '*.cc' -o -name '*.h' \) -print0 | sort -z |
  xargs -0 "$bin/clang-format" -i
echo "format.sh: done; run 'make lint' for what needs a person"

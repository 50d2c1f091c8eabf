#!/usr/bin/env bash
# mypy on the package as it installs (soilmodel/, identify/, planning/ map to soiltrack.* by
# setuptools package-dir, which mypy cannot follow in the source tree): install a copy into a
# temporary folder, then check `-p soiltrack` there. Settings: [tool.mypy] in pyproject.toml.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
# setuptools stages the build in ./build: a stale one would install deleted modules into the copy
rm -rf "$root/build"
python -m pip install -q --no-deps --target "$tmp/pkg" "$root" >/dev/null
cd "$tmp"
MYPYPATH="$tmp/pkg" python -m mypy --config-file "$root/pyproject.toml" -p soiltrack

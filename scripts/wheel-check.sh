#!/usr/bin/env bash
# Build artic's wheel, install it with constraints.txt in a fresh virtual environment
# outside the checkout, and run `artic --version` and a tiny stage there. Fails (non-zero)
# when the wheel lacks conf/, stages/, py.typed or LICENSE, or when the installed CLI fails.
# Usage: scripts/wheel-check.sh [PYTHON]  (PYTHON makes the fresh venv; default python3.11)
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
python=${1:-python3.11}
start=$(date +%s)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/artic-wheel-check.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
fail() { echo "wheel-check: FAILED: $*" >&2; exit 1; }

# 1. Build (build/ is setuptools' scratch folder; a stale one could carry removed modules).
rm -rf build
.venv/bin/python -m pip wheel -q --no-deps --no-build-isolation -w "$tmp/dist" . \
  > "$tmp/build.log" 2>&1 || { cat "$tmp/build.log" >&2; fail "pip wheel"; }
rm -rf build
wheel=$(ls "$tmp"/dist/artic-*.whl) || fail "no wheel in $tmp/dist"

# 2. Contents: every file of conf/, stages/ and models/ (as git tracks them), py.typed, LICENSE.
git ls-files conf stages models > "$tmp/expected" || fail "git ls-files"
.venv/bin/python - "$wheel" "$tmp/expected" <<'PY' || fail "wheel contents"
import sys, zipfile
names = set(zipfile.ZipFile(sys.argv[1]).namelist())
want = {"artic/" + line.strip() for line in open(sys.argv[2]) if line.strip()}
want |= {"artic/py.typed", "artic/__init__.py", "artic/cli/main.py"}
missing = sorted(want - names)
if not any(n.endswith(".dist-info/licenses/LICENSE") for n in names):
    missing.append("*.dist-info/licenses/LICENSE")
if missing:
    sys.exit(f"wheel-check: {len(missing)} file(s) missing from the wheel: {missing[:10]}")
print(f"wheel-check: {sys.argv[1].rsplit('/', 1)[-1]}: {len(names)} files, conf/, stages/ and models/ complete")
PY

# 3. A fresh venv outside the checkout, the wheel installed with the tested versions.
"$python" -m venv "$tmp/venv" || fail "venv"
"$tmp/venv/bin/python" -m pip install -q -c constraints.txt "$wheel" > "$tmp/install.log" 2>&1 \
  || { grep -v "^WARNING: Location" "$tmp/install.log" >&2; fail "pip install"; }

# 4. Run it from a folder outside the checkout, without ARTIC_CONF.
mkdir "$tmp/run"
cd "$tmp/run"
version=$("$repo/.venv/bin/python" -c 'import artic; print(artic.__version__)')
got=$(env -u ARTIC_CONF "$tmp/venv/bin/artic" --version) || fail "artic --version"
[ "$got" = "artic $version" ] || fail "artic --version printed '$got', want 'artic $version'"
where=$(env -u ARTIC_CONF "$tmp/venv/bin/python" -c \
  'from artic.config.compose import conf_dir; print(conf_dir())') || fail "conf_dir()"
case "$where" in
  "$tmp/venv/"*) ;;
  *) fail "the installed artic reads conf/ from $where, not from its package" ;;
esac
env -u ARTIC_CONF "$tmp/venv/bin/artic" generate-dataset debug=tiny out="$tmp/run/objects" \
  > "$tmp/run/log" 2>&1 || { cat "$tmp/run/log" >&2; fail "artic generate-dataset"; }
[ -f "$tmp/run/objects/manifest.json" ] || fail "no objects/manifest.json"
# the shipped models are found in the installed package, each listed by `artic models`
shipped=$(git -C "$repo" ls-files models | grep -c '/card.json$' || true)
listed=$(env -u ARTIC_CONF -u ARTIC_MODELS "$tmp/venv/bin/artic" models --json | "$tmp/venv/bin/python" -c \
  'import json, sys; print(sum(m["source"] == "shipped" for m in json.load(sys.stdin)))') \
  || fail "artic models"
[ "$listed" = "$shipped" ] || fail "artic models lists $listed shipped models, the repository ships $shipped"
echo "wheel-check: ok ($got, conf/ from the installed package, generate-dataset debug=tiny, $listed shipped models) in $(( $(date +%s) - start ))s"

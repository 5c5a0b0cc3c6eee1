#!/usr/bin/env bash
# Find a Python >= 3.12, create .venv, install bayesfric (+ test extras) into it.
# Idempotent: reinstalls only when pyproject.toml changed. Prints the venv's python path last.
#   scripts/bootstrap.sh            the venv (what `make main` needs)
#   scripts/bootstrap.sh --browser  the venv, and a headless Chromium for the report's browser
#                                   test when missing (what `make test` needs; apt-get as root)
set -euo pipefail
browser=0
for arg in "$@"; do
  case "$arg" in
    --browser) browser=1 ;;
    *) echo "bootstrap: unknown option $arg (known: --browser)" >&2; exit 2 ;;
  esac
done
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$here/.venv"

works() {  # does "$1" run and report Python >= 3.12?
  [ -n "$1" ] && "$1" -c 'import sys, venv; sys.exit(sys.version_info < (3, 12))' >/dev/null 2>&1
}

find_python() {
  local c
  # 1. explicit choice; 2. versioned/unversioned names on PATH (pyenv shims refuse to run unless
  # selected, so every candidate is executed, not just looked up); 3. interpreters installed by
  # pyenv, uv, or the system, addressed by path so no shim is involved.
  for c in "${BAYESFRIC_PYTHON:-}" python3.13 python3.12 python3; do
    if works "$c"; then command -v "$c" 2>/dev/null || echo "$c"; return 0; fi
  done
  local roots=("${PYENV_ROOT:-$HOME/.pyenv}/versions" "$HOME/.local/share/uv/python" /opt/python /usr/local /usr)
  for root in "${roots[@]}"; do
    for c in $(ls -d "$root"/*3.1[2-9]*/bin/python3 "$root"/bin/python3.1[2-9] 2>/dev/null | sort -rV); do
      if works "$c"; then echo "$c"; return 0; fi
    done
  done
  return 1
}

uv_args() {  # pip's configured indexes, find-links and constraints as uv options
  "$1" - <<'PY'
import shlex, subprocess
out = subprocess.run([__import__("sys").executable, "-m", "pip", "config", "list"], capture_output=True, text=True).stdout
flags = {"index-url": "--index-url", "extra-index-url": "--extra-index-url", "find-links": "--find-links",
         "constraint": "--constraint"}
args = ["--index-strategy", "unsafe-best-match"]  # pip's rule: the best version over every index
for line in out.splitlines():
    key, _, value = line.partition("=")
    flag = flags.get(key.rsplit(".", 1)[-1])
    if flag:
        for v in shlex.split(value)[0].split() if value else []:
            args += [flag, v]
print(" ".join(shlex.quote(a) for a in args))
PY
}

stamp="$(sha256sum "$here/pyproject.toml" | cut -c1-16)"
if [ ! -x "$venv/bin/python" ] || ! works "$venv/bin/python" || [ "$(cat "$venv/.stamp" 2>/dev/null)" != "$stamp" ]; then
  py="$(find_python)" || { echo "bootstrap: no Python >= 3.12 found (set BAYESFRIC_PYTHON=/path/to/python3.12)" >&2; exit 1; }
  echo "bootstrap: using $py ($("$py" --version 2>&1)) to build $venv" >&2
  rm -rf "$venv"
  "$py" -m venv "$venv"
  log="$here/.venv/install.log"
  # uv resolves and installs the same versions as pip in seconds instead of ~80 s (measured on the
  # 2-core machine: identical package list); it reads pip's configuration (indexes, find-links,
  # constraints) translated by uv_args below. Any failure falls back to plain pip.
  if ! { "$venv/bin/python" -m pip install uv && "$venv/bin/uv" pip install --python "$venv/bin/python" \
           $(uv_args "$venv/bin/python") -e "$here[test,dask]"; } >"$log" 2>&1; then
    echo "bootstrap: uv unavailable or failed, installing with pip (log: $log)" >&2
    if ! { "$venv/bin/python" -m pip install --upgrade pip && "$venv/bin/python" -m pip install -e "$here[test,dask]"; } >>"$log" 2>&1; then
      tail -30 "$log" >&2; echo "bootstrap: installation failed (full log: $log)" >&2; exit 1
    fi
  fi
  echo "$stamp" > "$venv/.stamp"
fi
# The report's browser test (tests/report/test_browser.py) needs a headless Chromium from the
# distribution: a test-only need, so only with --browser (`make test`), never for `make main`.
# Installed when missing and possible (root with apt-get); otherwise a hint.
if [ "$browser" = 1 ] && ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "bootstrap: installing chromium (apt-get) for the report's browser test" >&2
    { apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends chromium; } \
      >"$here/.venv/chromium-install.log" 2>&1 \
      || echo "bootstrap: could not install chromium (log: $here/.venv/chromium-install.log)" >&2
  else
    echo "bootstrap: no chromium; the browser test needs it (e.g. sudo apt-get install chromium)" >&2
  fi
fi
echo "$venv/bin/python"

#!/usr/bin/env bash
# Smoke check of models/: creates models/.venv from requirements.txt if missing (or stale), then
# runs the pytest subset without the `slow` marker (both variants built and traced, graph.json
# re-run by the numpy interpreter, mcu NNEF exported offline and checked in tract).
# Usage: bash models/smoke.sh [extra pytest args]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="$here/.venv"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$here/requirements.txt" | cut -d' ' -f1)"
if [[ ! -x "$venv/bin/python" || ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]]; then
  echo "models/smoke.sh: installing $venv (torch wheel is large; a few minutes)"
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --no-cache-dir -r "$here/requirements.txt"
  echo "$want" > "$stamp"
fi
cd "$here"
exec "$venv/bin/python" -m pytest -q -m "not slow" "$@"

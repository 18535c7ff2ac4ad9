"""Shared fixtures: a small sensor, a small scene, and the `eoir` command-line binary."""

import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

import eoir

REPO = Path(__file__).resolve().parents[2]

# A MultimIR with a 40 × 32 detector (same optics, pitch and electronics) keeps every test
# to a fraction of a second of engine time.
SMALL = {"detector.rows": 32, "detector.cols": 40}


@pytest.fixture(scope="session")
def cli() -> str:
    """Path of the `eoir` CLI: $EOIR_CLI, else target/release/eoir (built if missing)."""
    env = os.environ.get("EOIR_CLI")
    if env:
        return env
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    exe = target / "release" / "eoir"
    if not exe.exists():
        if shutil.which("cargo") is None:
            pytest.skip("no eoir CLI: set EOIR_CLI or install cargo")
        subprocess.run(["cargo", "build", "--release", "--bin", "eoir"], cwd=REPO, check=True)
    return str(exe)


@pytest.fixture(scope="session")
def small_sensor() -> eoir.Sensor:
    return eoir.load_sensor("multimir", overrides=SMALL)


@pytest.fixture(scope="session")
def small_scene(small_sensor) -> eoir.Cube:
    """The demo's thermal scene for the small sensor, 2× oversampled."""
    return eoir.demo_scene(small_sensor, oversampling=2, seed=3)


def read_tiff_u16(path) -> np.ndarray:
    """A minimal baseline-TIFF reader (uncompressed, 16-bit grey, strips), independent of
    eoir's own reader, to check the CLI's `dn.tiff`."""
    b = Path(path).read_bytes()
    endian = {b"II": "<", b"MM": ">"}[b[:2]]
    (magic, ifd) = struct.unpack(endian + "HI", b[2:8])
    assert magic == 42
    (n,) = struct.unpack(endian + "H", b[ifd:ifd + 2])
    tags = {}
    for i in range(n):
        tag, typ, count, value = struct.unpack(endian + "HHII", b[ifd + 2 + 12 * i: ifd + 14 + 12 * i])
        if typ == 3 and count == 1:  # SHORT stored in the first two bytes
            value = struct.unpack(endian + "H", b[ifd + 10 + 12 * i: ifd + 12 + 12 * i])[0]
        tags[tag] = (typ, count, value)

    def values(tag):
        typ, count, value = tags[tag]
        size = {3: 2, 4: 4}[typ]
        if count * size <= 4:
            raw = struct.pack(endian + "I", value)[: count * size] if typ == 4 else struct.pack(endian + "H", value)
            return list(struct.unpack(endian + ("I" if typ == 4 else "H") * count, raw))
        fmt = endian + ("I" if typ == 4 else "H") * count
        return list(struct.unpack(fmt, b[value: value + count * size]))

    width, height = tags[256][2], tags[257][2]
    assert tags[258][2] == 16 and tags.get(259, (3, 1, 1))[2] == 1
    data = b"".join(b[o: o + c] for o, c in zip(values(273), values(279)))
    return np.frombuffer(data, dtype=endian + "u2").reshape(height, width).astype(np.uint16)

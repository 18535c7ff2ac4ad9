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
    """A 16-bit grey baseline TIFF (see :func:`read_tiff`)."""
    a = read_tiff(path)
    assert a.dtype == np.uint16
    return a


def read_tiff_f32(path) -> np.ndarray:
    """A 32-bit float grey baseline TIFF (see :func:`read_tiff`)."""
    a = read_tiff(path)
    assert a.dtype == np.float32
    return a


def write_tiff_u16(path, image) -> None:
    """A minimal baseline-TIFF writer (little-endian, uncompressed, 16-bit grey, one
    strip), independent of eoir's writer, to hand frames to the CLI."""
    a = np.ascontiguousarray(image, dtype="<u2")
    h, w = a.shape
    data = a.tobytes()
    entries = [  # tag, type (3 SHORT, 4 LONG), value
        (256, 4, w), (257, 4, h), (258, 3, 16), (259, 3, 1), (262, 3, 1),
        (273, 4, 8), (277, 3, 1), (278, 4, h), (279, 4, len(data)), (339, 3, 1),
    ]
    ifd = 8 + len(data)
    out = bytearray(b"II" + struct.pack("<HI", 42, ifd) + data)
    out += struct.pack("<H", len(entries))
    for tag, typ, value in entries:
        if typ == 3:
            out += struct.pack("<HHIHH", tag, typ, 1, value, 0)
        else:
            out += struct.pack("<HHII", tag, typ, 1, value)
    out += struct.pack("<I", 0)
    Path(path).write_bytes(bytes(out))


def read_tiff(path) -> np.ndarray:
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
    bits = tags[258][2]
    fmt = tags.get(339, (3, 1, 1))[2]  # SampleFormat: 1 unsigned, 3 IEEE float
    assert tags.get(259, (3, 1, 1))[2] == 1
    data = b"".join(b[o: o + c] for o, c in zip(values(273), values(279)))
    if bits == 16 and fmt == 1:
        return np.frombuffer(data, dtype=endian + "u2").reshape(height, width).astype(np.uint16)
    assert bits == 32 and fmt == 3, (bits, fmt)
    return np.frombuffer(data, dtype=endian + "f4").reshape(height, width).astype(np.float32)

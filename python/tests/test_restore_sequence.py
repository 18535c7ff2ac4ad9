"""Multi-frame restoration from Python (issue 38): `eoir.restore_sequence` on an eoir
sequence folder gives the CLI's `eoir restore DIR` image bit for bit, registers within
0.1 px of the truth table, and refuses bad input."""

import json
import subprocess

import numpy as np
import pytest

import eoir
from conftest import read_tiff_f32

PSD = 1.1e-9  # rad²/Hz, flat 1–20 Hz: about 0.6 px rms of wander with the 100 mm optics
SETS = [
    "--set", "detector.rows=48", "--set", "detector.cols=48",
    "--set", "detector.defects.dead_fraction=0", "--set", "clock.frame_rate_hz=50",
    "--set", "motion.velocity_m_s=0.001",
]
WANDER = f"trajectory.wander={{kind = \"table\", frequency_hz = [1.0, 20.0], psd_rad2_per_hz = [{PSD}, {PSD}]}}"


@pytest.fixture(scope="module")
def sequence(cli, tmp_path_factory):
    """An 8-frame wandering bar-target sequence run by the CLI, and its CLI restoration."""
    d = tmp_path_factory.mktemp("seq")
    subprocess.run([cli, "scene", "bars", "-o", str(d / "s.hdr"), *SETS, "--margin-px", "6",
                    "--bands", "8"], check=True, capture_output=True)
    subprocess.run([cli, "run", "--quiet", *SETS, "--set", WANDER, str(d / "s.hdr"), "-o",
                    str(d / "seq"), "--frames", "8"], check=True, capture_output=True)
    subprocess.run([cli, "restore", str(d / "seq"), "-o", str(d / "r")], check=True,
                   capture_output=True)
    return d


def test_restore_sequence_matches_the_cli_and_the_truth(sequence):
    out = eoir.restore_sequence(sequence / "seq")
    cli_image = read_tiff_f32(sequence / "r" / "restored.tiff")
    assert out["restored"].shape == (96, 96)
    assert out["restored"].dtype == np.float32
    np.testing.assert_array_equal(out["restored"], cli_image)
    assert out["report"]["upsample"] == 2
    assert out["report"]["shift_residual_vs_truth_max_px"] < 0.1
    cli_report = json.loads((sequence / "r" / "restore.json").read_text())
    assert cli_report["shift_residual_vs_truth"]["max_px"] < 0.1
    # The truth table as registration, and an array input with the sensor given.
    truth = eoir.restore_sequence(sequence / "seq", register="truth")
    assert truth["report"]["registration"] == "given"
    sensor = eoir.load_sensor(str(sequence / "seq" / "config.toml"))
    stack = np.load(sequence / "seq" / "dn_stack.npy")
    arr = eoir.restore_sequence(stack, sensor, upsample=3)
    assert arr["restored"].shape == (144, 144)


def test_bad_input_is_refused(sequence):
    sensor = eoir.load_sensor(str(sequence / "seq" / "config.toml"))
    stack = np.load(sequence / "seq" / "dn_stack.npy")
    with pytest.raises(ValueError, match="different sizes"):
        eoir.restore_sequence([stack[0], stack[1][:-1]], sensor)
    with pytest.raises(ValueError, match="at least 2"):
        eoir.restore_sequence(stack[:1], sensor)
    with pytest.raises(ValueError, match="upsample"):
        eoir.restore_sequence(stack, sensor, upsample=0)
    with pytest.raises(ValueError, match="dn_stack.npy"):
        eoir.restore_sequence(sequence)

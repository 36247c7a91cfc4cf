"""The Python module against the `parallax` command line: the same run file renders the same
views bit for bit, plan and compare give the CLI's figures, and errors carry the CLI's messages.

Needs the CLI built (target/debug/parallax, or PARALLAX_CLI) and a Vulkan device (lavapipe).
"""

import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

import parallax

REPO = Path(__file__).resolve().parents[2]
CLI = Path(os.environ.get("PARALLAX_CLI", REPO / "target" / "debug" / "parallax"))

# Tiny runs: 4x2 views of 32x24 at 1 spp, one warm-up and one measured frame.
REPROJECT_ON_TWO_DEVICES = {"lf": "4x2", "resolution": "32x24", "spp": 1, "fake_devices": 2}
PATH_TRACE_FINE_ALL = {**REPROJECT_ON_TWO_DEVICES, "pipeline": "path-trace", "scheme": "fine-all"}


def cli(*words):
    """Runs the CLI; returns (exit status, stdout, stderr)."""
    assert CLI.is_file(), f"build the CLI first (cargo build): {CLI} is missing"
    done = subprocess.run([str(CLI), "-q", *map(str, words)], capture_output=True, text=True)
    return done.returncode, done.stdout, done.stderr


def cli_error(*words):
    """The CLI's exit status and error message (its first stderr line less `error: `)."""
    status, _, stderr = cli(*words)
    line = stderr.splitlines()[0]
    assert line.startswith("error: "), stderr
    return status, line[len("error: "):]


def write_run_file(path, settings):
    lines = [f"{key} = {value!r}" if isinstance(value, int) else f'{key} = "{value}"' for key, value in settings.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def decode_png(path):
    """An 8-bit non-interlaced PNG as a height x width x channels array: an independent reader
    for the CLI's view PNGs."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    assert depth == 8 and interlace == 0, header
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    raw, stride = zlib.decompress(idat), width * channels
    rows, previous = [], bytearray(stride)
    for y in range(height):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            left = line[i - channels] if i >= channels else 0
            up, up_left = previous[i], previous[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + left) & 255
            elif kind == 2:
                line[i] = (line[i] + up) & 255
            elif kind == 3:
                line[i] = (line[i] + (left + up) // 2) & 255
            elif kind == 4:
                p = left + up - up_left
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - up_left)
                line[i] = (line[i] + (left if pa <= pb and pa <= pc else up if pb <= pc else up_left)) & 255
        rows.append(bytes(line))
        previous = line
    return np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(height, width, channels)


def assert_same_views(rendered, cli_dir):
    report = rendered.report
    assert rendered.radiance.shape == (8, 24, 32, 3) and rendered.radiance.dtype == np.float32
    assert rendered.images.shape == (8, 24, 32, 3) and rendered.images.dtype == np.uint8
    assert rendered.radiance.max() > 0, "the default scene is lit: its views cannot be black"
    for v in range(8):
        cli_radiance = parallax.read_exr(cli_dir / f"view_{v:03}.exr")
        assert np.array_equal(rendered.radiance[v], cli_radiance), f"view {v}'s radiance differs"
        assert np.array_equal(rendered.images[v], decode_png(cli_dir / f"view_{v:03}.png")), f"view {v}'s PNG differs"
    cli_report = __import__("json").loads((cli_dir / "render.json").read_text())
    assert report["run"] == cli_report["run"]
    assert report["plan"] == cli_report["plan"] == rendered.plan


@pytest.fixture(scope="module")
def reproject_run(tmp_path_factory):
    """The reprojection pipeline on two devices, by the CLI and by the module from one run file."""
    folder = tmp_path_factory.mktemp("reproject")
    run_file = write_run_file(folder / "run.toml", REPROJECT_ON_TWO_DEVICES)
    status, _, stderr = cli("render", "--config", run_file, "--out-dir", folder / "cli")
    assert status == 0, stderr
    return folder / "cli", parallax.render(config=run_file, out_dir=folder / "python")


def test_a_run_file_renders_the_cli_views_bit_for_bit(reproject_run):
    cli_dir, rendered = reproject_run
    assert_same_views(rendered, cli_dir)
    assert rendered.report["pipeline"] == "reproject" and len(rendered.report["devices"]) == 2
    assert rendered.dot.startswith("digraph")


def test_keywords_render_the_cli_views_of_the_same_run_file(tmp_path):
    run_file = write_run_file(tmp_path / "run.toml", PATH_TRACE_FINE_ALL)
    status, _, stderr = cli("render", "--config", run_file, "--out-dir", tmp_path / "cli")
    assert status == 0, stderr
    settings = {k: v for k, v in PATH_TRACE_FINE_ALL.items() if k not in ("lf", "resolution")}
    light_field = parallax.LightField("4x2", resolution=(32, 24))
    rendered = parallax.render(parallax.Scene(), light_field, **settings)
    assert_same_views(rendered, tmp_path / "cli")
    assert rendered.report["scheme"] == "fine-all"


def test_plan_gives_the_cli_json_and_dot(tmp_path):
    summary, dot = parallax.plan(parallax.LightField("4x2", resolution=(32, 24)), fake_devices=2, scheme="fine-sources")
    status, _, stderr = cli("plan", "--lf", "4x2", "--resolution", "32x24", "--fake-devices", "2",
                            "--scheme", "fine-sources", "--json", tmp_path / "p.json", "--dot", tmp_path / "p.dot")
    assert status == 0, stderr
    assert summary == __import__("json").loads((tmp_path / "p.json").read_text())
    assert dot == (tmp_path / "p.dot").read_text()
    assert summary["views"] == 8 and summary["devices"] == 2


def test_compare_of_equal_views_finds_no_error(reproject_run):
    cli_dir, rendered = reproject_run
    overall = parallax.compare(rendered, cli_dir)["comparison"]["overall"]
    assert overall["flip"] == 0.0 and overall["rel_mse"] == 0.0 and overall["ssim"] == 1.0


def test_a_usage_error_carries_the_cli_message(tmp_path):
    status, message = cli_error("render", "--lf", "4x2", "--resolution", "0x24", "--out-dir", tmp_path / "cli")
    assert status == 2
    with pytest.raises(parallax.UsageError) as raised:
        parallax.render(light_field=parallax.LightField("4x2", resolution=(0, 24)))
    assert str(raised.value) == message == "invalid value '0x24' for '--resolution <WxH>': width 0 is outside 1..=32768"


def test_a_failed_run_carries_the_cli_message(tmp_path):
    status, message = cli_error("render", "--lf", "4x2", "--fake-devices", "9", "--out-dir", tmp_path / "cli")
    assert status == 1
    with pytest.raises(parallax.ParallaxError) as raised:
        parallax.render(light_field="4x2", fake_devices=9, out_dir=tmp_path / "python")
    assert not isinstance(raised.value, parallax.UsageError)
    assert str(raised.value) == message
    assert not (tmp_path / "python").exists(), "a failed run leaves nothing behind"


def test_a_missing_scene_carries_the_cli_message(tmp_path):
    missing = tmp_path / "missing.gltf"
    _, message = cli_error("render", "--scene", missing, "--out-dir", tmp_path / "cli")
    with pytest.raises(parallax.ParallaxError) as raised:
        parallax.Scene(missing)
    assert str(raised.value) == message


def test_the_speed_accuracy_example_draws_its_chart(tmp_path):
    pytest.importorskip("matplotlib")
    chart = tmp_path / "chart.png"
    example = REPO / "python" / "examples" / "speed_accuracy.py"
    done = subprocess.run(
        [sys.executable, str(example), "--resolution", "16x12", "--spp", "1,2", "--reference-spp", "4",
         "--frames", "1", "--out", str(chart)],
        capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert chart.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert done.stdout.count(" spp: ") == 4, done.stdout

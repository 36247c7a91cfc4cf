"""Parallax from Python: render light fields over one or many devices, get the views as NumPy
arrays, the render report, the plan, and the accuracy of a render against a reference.

Each call runs the `parallax` command of the same name in this process (the same code, flags
and checks), so a run file renders the same views here as on the command line, and a setting
no run could use raises the CLI's own message::

    import parallax
    lf = parallax.render(parallax.Scene(), parallax.LightField("4x2", resolution=(64, 48)),
                         spp=2, fake_devices=2)
    lf.radiance.shape   # (8, 48, 64, 3) float32, linear
    lf.images.shape     # (8, 48, 64, 3) uint8, the view PNGs
    lf.report["timing"] # render.json as a dict

Settings are `render`'s long flags with underscores (`spp=4`, `scheme="fine-all"`,
`no_denoise=True`, `camera=(0, 1, 4, 0, 1, 0, 0, 1, 0, 45)`), as in a TOML run file.
"""

import json
import os
import tempfile
from pathlib import Path

import numpy as np

from . import _native
from ._native import ParallaxError, UsageError

__all__ = [
    "ParallaxError",
    "UsageError",
    "Scene",
    "LightField",
    "Render",
    "render",
    "plan",
    "compare",
    "read_exr",
    "read_png",
    "run",
]


def run(*words):
    """Runs `parallax WORDS...` in this process, e.g. `run("plan", "--lf", "8x4")`; raises
    UsageError (the CLI's exit 2) or ParallaxError (exit 1) with the CLI's message."""
    _native.run([os.fspath(w) for w in words])


def read_exr(path, channels=("R", "G", "B")):
    """The named channels of an EXR as a float32 array of height x width x channels."""
    return _native.read_exr(os.fspath(path), list(channels))


def read_png(path):
    """A PNG as a uint8 array of height x width x channels."""
    return _native.read_png(os.fspath(path))


class Scene:
    """A scene, loaded (and checked) now: a glTF file (.gltf/.glb) or "default", the embedded
    one; with the camera and lights a render uses instead of the scene's own (`camera`: 10
    numbers eye, target, up, yfov in degrees; `sun`: to_sun xyz, irradiance[, angular radius];
    `sky`: r, g, b or zenith, horizon, ground rgb)."""

    def __init__(self, path="default", *, camera=None, sun=None, no_sun=False, sky=None,
                 allow_outside_files=False):
        self.path = os.fspath(path)
        self.info = _native.load_scene(self.path, allow_outside_files)
        self.camera, self.sun, self.no_sun, self.sky = camera, sun, no_sun, sky
        self.allow_outside_files = allow_outside_files

    def settings(self):
        return {"scene": self.path, "camera": self.camera, "sun": self.sun, "no_sun": self.no_sun,
                "sky": self.sky, "allow_outside_files": self.allow_outside_files}

    def __repr__(self):
        return f"Scene({self.path!r}, {self.info['triangles']} triangles)"


class LightField:
    """A light field's layout ("multiscopic", "nelf" or "COLSxROWS"), per-view resolution
    ((width, height) or "WxH"), spacing between neighbouring views (metres) and the distance
    of the zero-disparity plane (metres); None leaves render's default."""

    def __init__(self, layout="8x4", *, resolution=None, spacing=None, focus=None):
        if isinstance(resolution, (tuple, list)):
            resolution = "x".join(str(side) for side in resolution)
        self.layout, self.resolution, self.spacing, self.focus = layout, resolution, spacing, focus

    def settings(self):
        return {"lf": self.layout, "resolution": self.resolution, "spacing": self.spacing,
                "focus": self.focus}

    def __repr__(self):
        return f"LightField({self.layout!r}, resolution={self.resolution!r})"


class Render:
    """What a render left: the views of its last frame and its report.

    radiance: float32 array (views, height, width, 3), the linear radiance of the EXRs.
    images: uint8 array (views, height, width, channels), the view PNGs at the run's exposure.
    layers: with `layers=True`, by name: albedo and normal (views, height, width, 3), depth
        (views, height, width), holes: per view a (height, width) mask, 1 where hole filling
        path traced the pixel (None for a source view, which has none).
    report: render.json as a dict; plan: its plan summary; dot: the schedule in Graphviz DOT.
    out_dir: the folder holding the files (a temporary one lives as long as this object).
    """

    def __init__(self, out_dir, dot, keep_alive=None):
        self.out_dir = Path(out_dir)
        self._keep_alive = keep_alive
        self.report = json.loads((self.out_dir / "render.json").read_text())
        self.plan = self.report["plan"]
        self.dot = dot
        views = range(self.report["layout"]["views"])
        exrs = [self.out_dir / f"view_{v:03}.exr" for v in views]
        self.radiance = np.stack([read_exr(p) for p in exrs])
        self.images = np.stack([read_png(self.out_dir / f"view_{v:03}.png") for v in views])
        self.layers = {}
        if self.report["run"].get("layers"):
            for name, channels in _LAYERS.items():
                self.layers[name] = np.stack([read_exr(p, channels) for p in exrs])
            self.layers["depth"] = self.layers["depth"][..., 0]
            self.layers["holes"] = [_holes_of(p) for p in exrs]

    def __len__(self):
        return len(self.radiance)

    def __repr__(self):
        layout = self.report["layout"]
        return (f"Render({layout['views']} views of {layout['width']}x{layout['height']}, "
                f"{self.report['pipeline']}, {self.report['scheme']}, out_dir={str(self.out_dir)!r})")


_LAYERS = {"albedo": ("albedo.R", "albedo.G", "albedo.B"),
           "normal": ("normal.X", "normal.Y", "normal.Z"), "depth": ("depth.Z",)}


def _holes_of(exr):
    try:
        return read_exr(exr, ("holes.Y",))[..., 0]
    except ParallaxError as error:
        if "no channel holes.Y" not in str(error):
            raise
        return None  # a source view: path traced whole, no hole mask


def _flags(origin, settings):
    """The command-line flags of `settings` (run-file keys), unset ones left out."""
    table = {key: value for key, value in settings.items() if value is not None}
    for key, value in table.items():
        if isinstance(value, tuple):
            table[key] = list(value)
        elif isinstance(value, os.PathLike):
            table[key] = os.fspath(value)
    return _native.run_file_flags(origin, json.dumps(table))


def _with_denoise(settings, denoise):
    if denoise is not None:
        settings["no_denoise"] = not denoise
    return settings


def render(scene=None, light_field=None, *, config=None, out_dir=None, denoise=None, **settings):
    """Renders a light field as `parallax render` does and returns a Render.

    scene: a Scene or a path ("default" when neither it nor the run file names one).
    light_field: a LightField or a layout string such as "4x2".
    config: a run file (TOML, or a render.json) as `--config`; settings given here win.
    out_dir: keep the outputs there (created if missing); default: a temporary folder.
    denoise: False is `no_denoise=True`.
    settings: any other flag of render by its long name (spp, frames, still, pipeline, scheme,
        gpus, fake_devices, exposure, layers, max_depth, ...).
    """
    given = dict(settings)
    if isinstance(scene, Scene):
        given.update(scene.settings())
    elif scene is not None:
        given["scene"] = os.fspath(scene)
    if isinstance(light_field, LightField):
        given.update(light_field.settings())
    elif light_field is not None:
        given["lf"] = light_field
    keep_alive = None
    if out_dir is None:
        keep_alive = tempfile.TemporaryDirectory(prefix="parallax-render-")
        out_dir = keep_alive.name
    words = ["render"]
    if config is not None:
        words += ["--config", os.fspath(config)]
    words += _flags("render settings", _with_denoise(given, denoise))
    # The DOT goes beside, not into, --out-dir: that folder may not exist before the run.
    with tempfile.TemporaryDirectory(prefix="parallax-dot-") as folder:
        dot_path = os.path.join(folder, "plan.dot")
        run(*words, "--out-dir", os.fspath(out_dir), "--dot", dot_path)
        dot = Path(dot_path).read_text()
    return Render(out_dir, dot, keep_alive)


def plan(light_field=None, *, denoise=None, **settings):
    """Plans a light field as `parallax plan` does (no GPU): returns (summary dict, DOT text).
    Takes the layout, device and pipeline settings of render (gpus, fake_devices, pipeline,
    scheme, assign, sources, dot_detail, ...)."""
    given = dict(settings)
    if isinstance(light_field, LightField):
        given.update({k: v for k, v in light_field.settings().items() if k != "focus"})
    elif light_field is not None:
        given["lf"] = light_field
    with tempfile.TemporaryDirectory(prefix="parallax-plan-") as folder:
        json_path, dot_path = os.path.join(folder, "plan.json"), os.path.join(folder, "plan.dot")
        run("plan", *_flags("plan settings", _with_denoise(given, denoise)),
            "--json", json_path, "--dot", dot_path)
        return json.loads(Path(json_path).read_text()), Path(dot_path).read_text()


def compare(test, reference, *, exposure=None, allow_mismatch=False):
    """PSNR, SSIM, FLIP and relMSE of a render against a reference, as `parallax compare`:
    each side a Render, a light-field folder or an EXR. Returns compare's JSON as a dict: the
    pooled metrics under ["comparison"]["overall"] (psnr_linear_db, psnr_tonemapped_db, ssim,
    flip, rel_mse, ...), each view's under ["comparison"]["views"], and a chart point."""
    sides = [os.fspath(side.out_dir if isinstance(side, Render) else side) for side in (test, reference)]
    words = ["compare", *sides]
    if exposure is not None:
        words += ["--exposure", str(exposure)]
    if allow_mismatch:
        words.append("--allow-mismatch")
    with tempfile.TemporaryDirectory(prefix="parallax-compare-") as folder:
        json_path = os.path.join(folder, "compare.json")
        run(*words, "--json", json_path)
        return json.loads(Path(json_path).read_text())

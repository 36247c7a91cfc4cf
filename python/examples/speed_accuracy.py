"""Speed against accuracy: the paper's reprojection pipeline and path tracing of every view, at a
few sample counts, against a converged path-traced reference of the same light field.

    python python/examples/speed_accuracy.py --out speed_accuracy.png

Each point is one render: its mean GPU frame time (x) and its FLIP error against the reference
(y, lower is better), labelled with its samples per pixel.
"""

import argparse

import matplotlib

matplotlib.use("Agg")  # draws into a file; no display needed
import matplotlib.pyplot as plt

import parallax


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="default", help="glTF file or 'default'")
    parser.add_argument("--lf", default="4x2", help="light-field layout")
    parser.add_argument("--resolution", default="64x48", help="per-view resolution WxH")
    parser.add_argument("--spp", default="1,2,4", help="sample counts to measure")
    parser.add_argument("--reference-spp", type=int, default=64)
    parser.add_argument("--frames", type=int, default=3, help="measured frames per render")
    parser.add_argument("--fake-devices", type=int, default=1)
    parser.add_argument("--out", default="speed_accuracy.png", help="chart file (.png or .svg)")
    args = parser.parse_args()

    scene = parallax.Scene(args.scene)
    light_field = parallax.LightField(args.lf, resolution=args.resolution)
    # A still camera: a reference of a moving one would not exist.
    common = dict(still=True, fake_devices=args.fake_devices)
    reference = parallax.render(scene, light_field, pipeline="path-trace", spp=args.reference_spp, **common)

    figure, axes = plt.subplots(figsize=(6, 4))
    for pipeline in ("reproject", "path-trace"):
        times, errors = [], []
        for spp in (int(s) for s in args.spp.split(",")):
            rendered = parallax.render(scene, light_field, pipeline=pipeline, spp=spp, frames=args.frames, **common)
            overall = parallax.compare(rendered, reference)["comparison"]["overall"]
            times.append(rendered.report["timing"]["frame_gpu"]["mean_ms"])
            errors.append(overall["flip"])
            axes.annotate(f"{spp} spp", (times[-1], errors[-1]), textcoords="offset points", xytext=(4, 4))
            print(f"{pipeline:10} {spp:3} spp: {times[-1]:8.2f} ms  FLIP {errors[-1]:.4f}")
        axes.plot(times, errors, marker="o", label=pipeline)
    axes.set_xlabel("GPU frame time (ms)")
    axes.set_ylabel(f"FLIP against {args.reference_spp} spp path tracing")
    axes.set_title(f"{scene.info['name']}, {args.lf} views of {args.resolution}")
    axes.legend()
    figure.tight_layout()
    figure.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

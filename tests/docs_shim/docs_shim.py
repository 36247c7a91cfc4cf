#!/usr/bin/env python3
"""The commands of README.md's and docs/'s shell blocks, as tests/docs_blocks.rs runs them.

Installed under two names on the PATH of every block:
- `parallax` (also `target/release/parallax` in the block's folder): the test's build of the
  CLI, with the flags that size a run cut down so that lavapipe renders it in seconds (views
  larger than 96 pixels a side to 32);
- `cargo`: `cargo run [--release] [--features F] -- ARGS` is `parallax ARGS`, `cargo run --example
  NAME -- ARGS` the example's binary, and `cargo build`/`cargo install --path .` do nothing, since
  the test command has built every target already. Any other cargo call is refused, so a block
  this test cannot run fails instead of passing unseen.

Only sizes change: the subcommands, scenes, schemes, pipelines and file names are the block's
own, so a block that fails as written fails here too.
"""

import math
import os
import shlex
import sys

# A flag's value is cut to at most this (`--spp 4096` runs 4 samples, `--frames 60` 2 frames).
CAPS = {"--frames": 2, "--warmup": 1, "--spp": 4, "--chunk-spp": 4, "--repeats": 1,
        "--size-mib": 1, "--chunk-mib": 1}
# The longest side of a view; subcommands that render and name no size get this one.
SIDE = 32
# Views of at most this many pixels a side are left as the block gives them.
KEEP_SIDE = 96
RENDERING = {"render", "reference", "trace", "bench-rays"}


def tiny_resolution(value):
    width, height = (int(v) for v in value.split("x"))
    # Already small: kept, so that it still matches what a run file or matrix of the same block
    # names (a bench matrix's cells against the block's `reference`).
    if max(width, height) <= KEEP_SIDE:
        return value
    factor = max(1, math.ceil(max(width, height) / SIDE))
    return f"{max(4, width // factor)}x{max(4, height // factor)}"


def tiny(args):
    """`args` with every sizing flag cut down; `--gpus N` becomes `--fake-devices N` (lavapipe)."""
    out, i = [], 0
    while i < len(args):
        word = args[i]
        flag, eq, inline = word.partition("=")
        value = inline if eq else (args[i + 1] if i + 1 < len(args) else None)
        step = 1 if eq else 2
        if flag == "--resolution" and value:
            out += [flag, tiny_resolution(value)]
        elif flag in CAPS and value and value.isdigit():
            # 0 keeps its meaning (one chunk, no warm-up).
            out += [flag, str(min(int(value), CAPS[flag]))]
        elif flag == "--gpus" and value:
            out += ["--fake-devices", value]
        elif flag == "--common" and value:
            out += [flag, shlex.join(tiny(shlex.split(value)))]
        else:
            out.append(word)
            step = 1
        i += step
    subcommand = next((w for w in args if not w.startswith("-")), None)
    # A reference traces whole chunks (16 samples unless told): its cut --spp is one chunk.
    if subcommand == "reference" and "--chunk-spp" not in args and "--spp" in out:
        out += ["--chunk-spp", out[out.index("--spp") + 1]]
    if subcommand in RENDERING and not any(w.split("=")[0] == "--resolution" for w in args):
        out += ["--resolution", f"{SIDE}x{SIDE * 3 // 4}"]
    return out


def run(binary, args):
    os.execv(binary, [binary, *tiny(args)])


def cargo(args):
    if args[:1] == ["build"] or args[:3] == ["install", "--path", "."]:
        return
    if args[:1] == ["run"] and "--" in args:
        split = args.index("--")
        options, rest = args[1:split], args[split + 1:]
        if "--example" in options:
            name = options[options.index("--example") + 1]
            run(os.path.join(os.environ["PARALLAX_DOCS_EXAMPLES"], name), rest)
        run(os.environ["PARALLAX_DOCS_BIN"], rest)
    sys.exit(f"docs shim: `cargo {shlex.join(args)}` is not a command this test runs: "
             "give the block's commands through cargo run/build, or mark the block `text`")


if __name__ == "__main__":
    name = os.path.basename(sys.argv[0])
    if name == "cargo":
        cargo(sys.argv[1:])
    else:
        run(os.environ["PARALLAX_DOCS_BIN"], sys.argv[1:])

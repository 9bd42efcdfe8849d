#!/usr/bin/env python3
"""Path tracing against gradient-domain path tracing on the Cornell box.

Renders the bundled Cornell box with pt and gpt at a range of samples per
pixel, reconstructs each gpt render's buffers with the L1 and L2 screened
Poisson solvers (gdr.reconstruct), and plots the relative MSE of each image
against a high-sample pt reference, over spp, into a PNG.

    PYTHONPATH=build/python python3 examples/python/render_and_plot.py --out relmse.png

The defaults took 20 s on a shared two-core machine; --width, --spp and --ref-spp
make it quicker or more precise. The error includes the reference's own
noise, which --ref-spp lowers.
"""
import argparse
import os
import sys
import time

import matplotlib

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt  # noqa: E402

import gdr  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_SCENE = os.path.normpath(os.path.join(HERE, "..", "..", "scenes", "cornell-box", "scene.json"))


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default=DEFAULT_SCENE, help="scene file (default: the bundled Cornell box)")
    p.add_argument("--width", type=int, default=128, help="image width in pixels; the height keeps the aspect ratio")
    p.add_argument("--spp", default="1,2,4,8,16,32", help="comma-separated samples per pixel to measure")
    p.add_argument("--ref-spp", type=int, default=1024, help="samples per pixel of the pt reference")
    p.add_argument("--threads", type=int, default=0, help="worker threads (0: all cores)")
    p.add_argument("--out", default="relmse.png", help="the plot (PNG)")
    args = p.parse_args(argv)
    try:
        args.spp = sorted({int(s) for s in args.spp.split(",")})
    except ValueError:
        p.error(f"--spp expects comma-separated integers, got {args.spp!r}")
    if not args.spp or args.spp[0] < 1 or args.ref_spp < 1 or args.width < 1:
        p.error("--spp, --ref-spp and --width must be positive")
    if not args.out.lower().endswith(".png"):
        p.error(f"--out must name a .png file, got {args.out!r}")
    return args


def main(argv=None):
    args = parse_args(argv)
    scene = gdr.load_scene(args.scene)
    scene.set_resolution(args.width, 0)
    if os.path.abspath(args.out) in (os.path.abspath(f) for f in scene.inputs):
        sys.exit(f"render_and_plot: {args.out} is an input of the scene; choose another --out")
    print(f"{scene.path}: {scene.width}x{scene.height}, reference: pt at {args.ref_spp} spp")

    # The reference uses a seed of its own, so its noise is independent of every measured render's.
    ref = gdr.render(scene, integrator="pt", spp=args.ref_spp, seed=1_000_003, threads=args.threads)["color"]

    curves = {"pt": [], "gpt + L1": [], "gpt + L2": []}
    seconds = {name: [] for name in curves}
    print(f"{'spp':>6} {'pt':>12} {'gpt + L1':>12} {'gpt + L2':>12}   (relMSE, thesis convention)")
    for spp in args.spp:
        pt = gdr.render(scene, integrator="pt", spp=spp, seed=spp, threads=args.threads)
        curves["pt"].append(gdr.metrics.relmse(pt["color"], ref))
        seconds["pt"].append(pt.stats.seconds)
        # The reconstructions are done here, through gdr.reconstruct, rather than inside the render.
        gpt = gdr.render(scene, integrator="gpt", spp=spp, seed=spp, threads=args.threads,
                         params={"reconstruct": "none"})
        buffers = (gpt["primal"], gpt["dx"], gpt["dy"])
        for name, method in (("gpt + L1", "poisson-l1"), ("gpt + L2", "poisson-l2")):
            t = time.perf_counter()
            image = gdr.reconstruct(*buffers, method=method, direct=gpt["direct"])
            seconds[name].append(gpt.stats.seconds + time.perf_counter() - t)
            curves[name].append(gdr.metrics.relmse(image, ref))
        print(f"{spp:>6} " + " ".join(f"{curves[n][-1]:>12.5g}" for n in curves))

    fig, ax = plt.subplots(figsize=(6, 4.5), dpi=100)
    for name, errors in curves.items():
        ax.loglog(args.spp, errors, "o-", label=name)
    ax.set_xlabel("samples per pixel")
    ax.set_ylabel("relMSE: mean (x - r)² / (r² + 0.01)")
    name = os.path.basename(os.path.dirname(scene.path))
    ax.set_title(f"{name} {scene.width}x{scene.height}, reference pt {args.ref_spp} spp")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out)
    total = {n: sum(s) for n, s in seconds.items()}
    print("render seconds in all: " + ", ".join(f"{n} {s:.2f}" for n, s in total.items()))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

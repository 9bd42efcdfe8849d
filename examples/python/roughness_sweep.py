"""Roughness sweep: a scene built from a Python dict (meshes from numpy arrays),
a glossy floor whose roughness is changed in place with gdr.traverse, PT and
G-PT rendered at a few sample counts for each roughness, and their relMSE
against a high-spp reference plotted against render time (matplotlib, Agg)
to a PNG. A plain script with `# %%` cells (editors run them as a notebook).

    python3 examples/python/roughness_sweep.py --out sweep.png

The test suite runs it tiny (--width 24 --spp 1,2 --ref-spp 16 --roughness
0.05,0.4). Times are wall-clock seconds of this machine; on a loaded machine
they show the trend only.
"""
# %% Options
import argparse
import sys

import numpy as np

import gdr


def options(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=96, help="image width and height (pixels)")
    ap.add_argument("--spp", default="2,4,8,16", help="comma-separated sample counts of PT and G-PT")
    ap.add_argument("--ref-spp", type=int, default=512, help="samples per pixel of each reference (PT)")
    ap.add_argument("--roughness", default="0.02,0.1,0.4", help="comma-separated GGX alphas of the floor")
    ap.add_argument("--threads", type=int, default=0, help="render threads (0: all cores)")
    ap.add_argument("--out", required=True, help="the plot (.png)")
    a = ap.parse_args(argv)

    def numbers(text, kind, name, low):
        try:
            values = [kind(x) for x in text.split(",")]
        except ValueError:
            ap.error(f"--{name}: expected comma-separated numbers, got '{text}'")
        if not values or any(not v > low for v in values):
            ap.error(f"--{name}: every value must be above {low}, got '{text}'")
        return values

    a.spp = numbers(a.spp, int, "spp", 0)
    a.roughness = numbers(a.roughness, float, "roughness", 0)
    if a.width < 4:
        ap.error(f"--width must be at least 4, got {a.width}")
    if a.ref_spp < 1:
        ap.error(f"--ref-spp must be positive, got {a.ref_spp}")
    if not a.out.lower().endswith(".png"):
        ap.error(f"--out must name a .png file, got '{a.out}'")
    return a


# %% The scene, as a dict: a glossy floor, a back wall and an emitting quad, by numpy arrays
def quad(corners):
    """Vertices (4, 3) and two triangles of a quad given counter-clockwise as seen from its front."""
    return np.asarray(corners, dtype=np.float32), np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)


def scene_dict(width):
    floor_v, floor_t = quad([[-2, 0, 2], [2, 0, 2], [2, 0, -2], [-2, 0, -2]])
    wall_v, wall_t = quad([[-2, 0, -2], [2, 0, -2], [2, 2, -2], [-2, 2, -2]])
    light_v, light_t = quad([[-0.4, 1.2, -1.2], [-0.4, 0.4, -1.2], [0.4, 0.4, -1.2], [0.4, 1.2, -1.2]])
    return {
        "camera": {"position": [0, 0.9, 2.6], "target": [0, 0.4, -0.5], "up": [0, 1, 0], "fov": 45,
                   "width": width, "height": width},
        "meshes": [
            {"vertices": floor_v, "triangles": floor_t, "material": "floor"},
            {"vertices": wall_v, "triangles": wall_t, "material": "wall"},
            {"vertices": light_v, "triangles": light_t, "material": "light"},
        ],
        "materials": {
            "floor": {"type": "roughconductor", "ks": [0.9, 0.85, 0.8], "alpha": 0.1},
            "wall": {"type": "diffuse", "kd": [0.5, 0.5, 0.55]},
            "light": {"type": "diffuse", "kd": [0, 0, 0], "ke": [12, 11, 9]},
        },
    }


# %% Sweep: for each roughness, a reference and PT / G-PT at each spp
def sweep(a):
    scene = gdr.load_dict(scene_dict(a.width))
    params = gdr.traverse(scene)
    rows = []  # (alpha, spp, pt seconds, pt relMSE, gpt seconds, gpt relMSE)
    for alpha in a.roughness:
        params["materials.floor.alpha"] = alpha
        params.update()  # the same Scene object, rebuilt with the new roughness
        ref = gdr.render(scene, integrator="pt", spp=a.ref_spp, seed=1000, threads=a.threads)["color"]
        for spp in a.spp:
            pt = gdr.render(scene, integrator="pt", spp=spp, seed=1, threads=a.threads)
            gpt = gdr.render(scene, integrator="gpt", spp=spp, seed=1, threads=a.threads)
            rows.append((alpha, spp, pt.stats.seconds, gdr.metrics.relmse(pt["color"], ref),
                         gpt.stats.seconds, gdr.metrics.relmse(gpt["reconstruction_weighted"], ref)))
    return rows


# %% Plot relMSE against time, one panel per roughness
def plot(rows, roughness, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(roughness), figsize=(4 * len(roughness), 3.6), squeeze=False)
    for ax, alpha in zip(axes[0], roughness):
        r = [row for row in rows if row[0] == alpha]
        ax.loglog([x[2] for x in r], [x[3] for x in r], "o-", label="PT")
        ax.loglog([x[4] for x in r], [x[5] for x in r], "s-", label="G-PT (weighted)")
        for x in r:
            ax.annotate(f"{x[1]}", (x[4], x[5]), fontsize=7, textcoords="offset points", xytext=(3, 3))
        ax.set_title(f"floor roughness alpha = {alpha:g}")
        ax.set_xlabel("render time (s)")
        ax.set_ylabel("relMSE")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=100)


# %% Run
def main(argv=None):
    a = options(argv)
    rows = sweep(a)
    print("alpha  spp  pt_s     pt_relmse  gpt_s    gpt_relmse")
    for alpha, spp, pt_s, pt_e, gpt_s, gpt_e in rows:
        print(f"{alpha:<6g} {spp:<4d} {pt_s:<8.3f} {pt_e:<10.5f} {gpt_s:<8.3f} {gpt_e:.5f}")
    plot(rows, a.roughness, a.out)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    sys.exit(main())

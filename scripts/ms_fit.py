#!/usr/bin/env python3
"""Fit and evaluation of the view march's multiple-scattering octaves
(docs/multiple-scattering.md). Python 3 standard library only.

  scripts/ms_fit.py truths [--spp 256]      render the pathtrace truths (half the camera size) into TRUTHS
  scripts/ms_fit.py fit [--method raymarch] [--grid "N=2,3 a=0.5,0.75 b=0.2 c=0.5"]
                                            grid search of N, a, b, c on the fit scenes (default grid: GRID)
  scripts/ms_fit.py table --ms "N a b c"     rel-L2 table on the report scenes (ms=off vs octaves)

Every comparison is `lucent compare IMAGE TRUTH --block 8`: 8x8 block averages,
which remove most of the truth's Monte Carlo noise (see the doc for its size).
Environment: LUCENT (default build/lucent), TRUTHS (a folder of SCENE.exr;
default build/ms_truths), OUT (renders, default a temporary folder).
"""
import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LUCENT = os.environ.get("LUCENT", os.path.join(ROOT, "build", "lucent"))
TRUTHS = os.environ.get("TRUTHS", os.path.join(ROOT, "build", "ms_truths"))
FIT_SCENES = ["smoke_box", "dusty_room", "spot_shaft"]
REPORT_SCENES = ["demo", "bunny_fog", "cube_torus", "layered_cube", "homogeneous_sphere"]
GRID = {
    "N": [2, 3, 4, 6],
    "a": [0.25, 0.5, 0.75],
    "b": [0.4, 0.55, 0.7, 0.85],
    "c": [0.25, 0.5, 0.85],
}


def half_size(scene):
    with open(os.path.join(ROOT, "scenes", scene + ".json")) as f:
        cam = json.load(f)["camera"]
    return "%dx%d" % (cam["width"] // 2, cam["height"] // 2)


def run(args):
    env = dict(os.environ, LUCENT_QUIET="1")
    p = subprocess.run([LUCENT] + args, cwd=ROOT, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit("lucent %s failed: %s" % (" ".join(args), p.stderr.strip()))
    return p.stdout


def truth(scene):
    return os.path.join(TRUTHS, scene + ".exr")


def render(out_dir, scene, method, ms, backend="cpu"):
    """ms: None (ms=off) or (N, a, b, c). Returns the image path."""
    sets = []
    tag = "off"
    if ms is not None:
        n, a, b, c = ms
        tag = "%d_%g_%g_%g" % (n, a, b, c)
        sets = ["--set", method + ".ms=octaves", "--set", "%s.ms_octaves=%d" % (method, n),
                "--set", "%s.ms_a=%g" % (method, a), "--set", "%s.ms_b=%g" % (method, b),
                "--set", "%s.ms_c=%g" % (method, c)]
    out = os.path.join(out_dir, "%s.%s.%s.exr" % (scene, method, tag))
    run(["render", "scenes/%s.json" % scene, "--method", method, "--backend", backend, "--size", half_size(scene)]
        + sets + ["-o", out])
    return out


def compare(img, scene):
    return json.loads(run(["compare", img, truth(scene), "--block", "8", "--json"]))


def cmd_truths(a):
    os.makedirs(TRUTHS, exist_ok=True)
    for s in FIT_SCENES + REPORT_SCENES:
        if os.path.exists(truth(s)):
            continue
        print("truth:", s, flush=True)
        run(["render", "scenes/%s.json" % s, "--method", "pathtrace", "--set", "pathtrace.spp=%d" % a.spp,
             "--size", half_size(s), "-o", truth(s)])


def cmd_fit(a):
    grid = dict(GRID)
    for item in (a.grid or "").split():
        k, v = item.split("=")
        grid[k] = [int(x) if k == "N" else float(x) for x in v.split(",")]
    scenes = a.scenes.split(",") if a.scenes else FIT_SCENES
    out_dir = os.environ.get("OUT") or tempfile.mkdtemp(prefix="ms_fit")
    base = {s: compare(render(out_dir, s, a.method, None), s)["rel_l2"] for s in scenes}
    print("ms=off: " + " ".join("%s %.4f" % (s, base[s]) for s in scenes), flush=True)
    rows = []
    for n, av, bv, cv in itertools.product(grid["N"], grid["a"], grid["b"], grid["c"]):
        ms = (n, av, bv, cv)
        errs = []
        for s in scenes:
            img = render(out_dir, s, a.method, ms)
            errs.append(compare(img, s)["rel_l2"])
            os.remove(img)
        score = sum(errs) / len(errs)
        rows.append((score, ms, errs))
        print("N=%d a=%g b=%g c=%g  %s  mean %.4f" % (n, av, bv, cv, " ".join("%.4f" % e for e in errs), score),
              flush=True)
    rows.sort(key=lambda r: r[0])
    print("\nbest 5 (mean block-8 rel-L2 over %s):" % ", ".join(scenes))
    for score, ms, errs in rows[:5]:
        print("  N=%d a=%g b=%g c=%g  %s  mean %.4f" % (ms + (" ".join("%.4f" % e for e in errs), score)))
    print("\nbest per scene:")
    for k, s in enumerate(scenes):
        score, ms, errs = min(rows, key=lambda r: r[2][k])
        print("  %s: N=%d a=%g b=%g c=%g  rel-L2 %.4f (ms=off %.4f)" % ((s,) + ms + (errs[k], base[s])))


def cmd_table(a):
    out_dir = os.environ.get("OUT") or tempfile.mkdtemp(prefix="ms_table")
    n, av, bv, cv = a.ms.split()
    ms = (int(n), float(av), float(bv), float(cv))
    scenes = FIT_SCENES + REPORT_SCENES if a.all else REPORT_SCENES
    print("| scene | method | rel-L2 ms=off | rel-L2 octaves | mean ratio off | mean ratio octaves |")
    print("|---|---|---|---|---|---|")
    for s in scenes:
        for m in a.methods.split(","):
            r0 = compare(render(out_dir, s, m, None), s)
            r1 = compare(render(out_dir, s, m, ms), s)
            print("| %s | %s | %.3f | %.3f | %.3f | %.3f |" % (s, m, r0["rel_l2"], r1["rel_l2"], r0["mean_ratio"],
                                                           r1["mean_ratio"]), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("truths")
    t.add_argument("--spp", type=int, default=256)
    f = sub.add_parser("fit")
    f.add_argument("--method", default="raymarch")
    f.add_argument("--scenes", help="comma list instead of the fit scenes (e.g. to see the model's ceiling)")
    f.add_argument("--grid", help='values per parameter replacing the default grid, e.g. "N=2,3 b=0.1,0.2"')
    tb = sub.add_parser("table")
    tb.add_argument("--ms", required=True, help='"N a b c"')
    tb.add_argument("--methods", default="raymarch,afm")
    tb.add_argument("--all", action="store_true", help="the fit scenes too")
    a = ap.parse_args()
    {"truths": cmd_truths, "fit": cmd_fit, "table": cmd_table}[a.cmd](a)


if __name__ == "__main__":
    main()

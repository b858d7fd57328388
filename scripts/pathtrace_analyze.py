#!/usr/bin/env python3
"""Analysis for docs/pathtrace.md (Python standard library only).

  ratio SINGLE.pfm FULL.pfm OUT.png [--max R]
      Multiple-to-single scattering ratio M/S with M = FULL - SINGLE (depth >= 2)
      and S = SINGLE (depth 1). Writes a false-colour PNG of the per-pixel ratio
      (3x3 box-filtered to tame noise; pixels whose single scattering is below
      1 % of the image's 99th percentile are drawn dark grey) and prints one
      JSON line: the energy-weighted mean sum(M)/sum(S), the 3x3 tile ratios
      (rows top to bottom) and percentiles of the per-pixel ratio.
  noise REF.pfm SPP:IMG.pfm ...
      rel-L2 of each image against REF; prints "spp rel_l2" lines.
  bar OUT.png [--max R]
      The colour scale of `ratio` as a 256 x 16 strip (left 0, right R).
  mean IMG.pfm
      Mean of each channel.
  boxcmp A.pfm REF.pfm [--box K] [--mask M.pfm [--outside]] [--ratio]
      rel-L2 of A against REF after averaging both over K x K blocks (default 4;
      a partial block at the edge is dropped), which tames a noisy REF's
      per-pixel variance (by about K) while keeping structure coarser than K.
      `lucent compare --block K` computes the same over the whole image.
      --mask: only the blocks in which every pixel of M is non-zero (with
      --outside: every pixel zero), e.g. an object without its silhouette.
      --ratio: print the mean ratio sum A / sum REF over those blocks too.
  exitance W:MU:IMG.pfm ...
      Exitance 2 pi sum_k W_k MU_k L_k per channel, L_k the mean radiance of
      an image seen from direction cosine MU_k: quadrature of the radiance
      leaving a uniformly lit surface over the hemisphere (W, MU: Gauss-
      Legendre weights and nodes on [0, 1]).
  average OUT.pfm A.pfm B.pfm ...
      The pixel-wise mean of the images (independent renders of one scene).
  png IMG.pfm OUT.png [--exposure E]
  pair A.pfm B.pfm OUT.png [--exposure E]
      Display PNG (2^E scale, exact sRGB curve, clamped); pair puts A and B
      side by side with a 4-pixel black gap.
"""
import json
import math
import struct
import sys
import zlib


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        c = 3 if kind == b"PF" else 1
        n = w * h * c
        data = struct.unpack(("<" if scale < 0 else ">") + "%df" % n, f.read(4 * n))
    rows = [data[(h - 1 - y) * w * c:(h - y) * w * c] for y in range(h)]  # PFM stores bottom-up
    if c == 1:
        rows = [[v for v in r for _ in range(3)] for r in rows]
    return w, h, [v for r in rows for v in r]


def write_pfm(path, w, h, rgb):
    rows = [rgb[(h - 1 - y) * w * 3:(h - y) * w * 3] for y in range(h)]  # bottom-up
    with open(path + ".tmp", "wb") as f:
        f.write(b"PF\n%d %d\n-1\n" % (w, h))
        f.write(struct.pack("<%df" % (w * h * 3), *[v for r in rows for v in r]))
    import os
    os.replace(path + ".tmp", path)


def write_png(path, w, h, rgb8):
    raw = b"".join(b"\x00" + bytes(rgb8[y * w * 3:(y + 1) * w * 3]) for y in range(h))

    def chunk(tag, data):
        c = struct.pack(">I", len(data)) + tag + data
        return c + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    with open(path + ".tmp", "wb") as f:
        f.write(png)
    import os
    os.replace(path + ".tmp", path)


# Perceptual-ish ramp: black, purple, red, orange, yellow, white (display sRGB).
STOPS = [(0.0, (0, 0, 0)), (0.2, (72, 20, 110)), (0.4, (180, 30, 80)), (0.6, (235, 100, 30)),
         (0.8, (250, 200, 40)), (1.0, (255, 255, 240))]


def ramp(t):
    t = min(max(t, 0.0), 1.0)
    for (t0, c0), (t1, c1) in zip(STOPS, STOPS[1:]):
        if t <= t1:
            a = (t - t0) / (t1 - t0)
            return tuple(int(round(c0[i] + a * (c1[i] - c0[i]))) for i in range(3))
    return STOPS[-1][1]


def lum(rgb, i):
    return 0.2126 * rgb[3 * i] + 0.7152 * rgb[3 * i + 1] + 0.0722 * rgb[3 * i + 2]


def percentile(vals, p):
    if not vals:
        return float("nan")
    s = sorted(vals)
    return s[min(len(s) - 1, int(p * len(s)))]


def cmd_ratio(args):
    single, full, out = args[0], args[1], args[2]
    rmax = float(args[args.index("--max") + 1]) if "--max" in args else 2.0
    w, h, s = read_pfm(single)
    w2, h2, f = read_pfm(full)
    assert (w, h) == (w2, h2)
    S = [lum(s, i) for i in range(w * h)]
    F = [lum(f, i) for i in range(w * h)]
    thresh = 0.01 * percentile(S, 0.99)
    sum_s = sum(S)
    sum_m = sum(F) - sum_s
    # 3x3 box filter of M and S before dividing (ratio of local sums)
    def box(a, x, y):
        acc = 0.0
        for j in range(max(0, y - 1), min(h, y + 2)):
            for i in range(max(0, x - 1), min(w, x + 2)):
                acc += a[j * w + i]
        return acc
    M = [F[i] - S[i] for i in range(w * h)]
    rgb8 = []
    ratios = []
    for y in range(h):
        for x in range(w):
            bs = box(S, x, y)
            if S[y * w + x] < thresh or bs <= 0:
                rgb8 += [40, 40, 40]
                continue
            r = box(M, x, y) / bs
            ratios.append(r)
            rgb8 += list(ramp(r / rmax))
    write_png(out, w, h, rgb8)
    tiles = []
    for ty in range(3):
        row = []
        for tx in range(3):
            ts = tm = 0.0
            for y in range(ty * h // 3, (ty + 1) * h // 3):
                for x in range(tx * w // 3, (tx + 1) * w // 3):
                    ts += S[y * w + x]
                    tm += M[y * w + x]
            row.append(round(tm / ts, 3) if ts > 0 else None)
        tiles.append(row)
    print(json.dumps({"mean_ratio": round(sum_m / sum_s, 4) if sum_s > 0 else None, "tiles": tiles,
                      "p10": round(percentile(ratios, 0.1), 3), "p50": round(percentile(ratios, 0.5), 3),
                      "p90": round(percentile(ratios, 0.9), 3), "lit_pixels": len(ratios), "pixels": w * h}))


def cmd_noise(args):
    w, h, ref = read_pfm(args[0])
    den = math.sqrt(sum(v * v for v in ref))
    for a in args[1:]:
        spp, path = a.split(":", 1)
        _, _, img = read_pfm(path)
        num = math.sqrt(sum((p - q) ** 2 for p, q in zip(img, ref)))
        print(spp, "%.6g" % (num / den))


def cmd_bar(args):
    out = args[0]
    w, h = 256, 16
    rgb8 = []
    for _ in range(h):
        for x in range(w):
            rgb8 += list(ramp(x / (w - 1)))
    write_png(out, w, h, rgb8)


def srgb8(v):
    v = max(v, 0.0)
    e = 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    return int(round(min(e, 1.0) * 255))


def exposure_of(args):
    return 2.0 ** float(args[args.index("--exposure") + 1]) if "--exposure" in args else 1.0


def cmd_png(args):
    w, h, d = read_pfm(args[0])
    k = exposure_of(args)
    write_png(args[1], w, h, [srgb8(v * k) for v in d])


def cmd_pair(args):
    w, h, a = read_pfm(args[0])
    w2, h2, b = read_pfm(args[1])
    assert (w, h) == (w2, h2)
    k = exposure_of(args)
    gap = 4
    rgb8 = []
    for y in range(h):
        rgb8 += [srgb8(v * k) for v in a[y * w * 3:(y + 1) * w * 3]] + [0] * (3 * gap)
        rgb8 += [srgb8(v * k) for v in b[y * w * 3:(y + 1) * w * 3]]
    write_png(args[2], 2 * w + gap, h, rgb8)


def cmd_mean(args):
    w, h, d = read_pfm(args[0])
    n = w * h
    print(" ".join("%.6g" % (sum(d[c::3]) / n) for c in range(3)))


def cmd_boxcmp(args):
    k = int(args[args.index("--box") + 1]) if "--box" in args else 4
    w, h, a = read_pfm(args[0])
    w2, h2, b = read_pfm(args[1])
    assert (w, h) == (w2, h2), "images differ in size"
    mask = None
    if "--mask" in args:
        wm, hm, mask = read_pfm(args[args.index("--mask") + 1])
        assert (wm, hm) == (w, h), "mask differs in size"
    outside = "--outside" in args
    num = den = suma = sumb = 0.0
    for by in range(h // k):
        for bx in range(w // k):
            if mask is not None:
                inside = [any(mask[(y * w + x) * 3 + c] != 0 for c in range(3))
                          for y in range(by * k, by * k + k) for x in range(bx * k, bx * k + k)]
                if not (all(inside) if not outside else not any(inside)):
                    continue
            for c in range(3):
                sa = sb = 0.0
                for y in range(by * k, by * k + k):
                    for x in range(bx * k, bx * k + k):
                        sa += a[(y * w + x) * 3 + c]
                        sb += b[(y * w + x) * 3 + c]
                num += (sa - sb) ** 2
                den += sb * sb
                suma += sa
                sumb += sb
    if den == 0:
        sys.exit("boxcmp: REF is zero over the selected blocks (or none were selected)")
    if "--ratio" in args:
        print("%.6g %.6g" % (math.sqrt(num / den), suma / sumb))
    else:
        print("%.6g" % math.sqrt(num / den))


def cmd_exitance(args):
    m = [0.0, 0.0, 0.0]
    for a in args:
        w, mu, path = a.split(":", 2)
        iw, ih, d = read_pfm(path)
        for c in range(3):
            m[c] += 2 * math.pi * float(w) * float(mu) * sum(d[c::3]) / (iw * ih)
    print(" ".join("%.4f" % v for v in m))


def cmd_average(args):
    imgs = [read_pfm(p) for p in args[1:]]
    w, h, _ = imgs[0]
    assert all((i[0], i[1]) == (w, h) for i in imgs), "images differ in size"
    n = len(imgs)
    write_pfm(args[0], w, h, [sum(v) / n for v in zip(*(i[2] for i in imgs))])


if __name__ == "__main__":
    cmds = {"ratio": cmd_ratio, "noise": cmd_noise, "bar": cmd_bar, "mean": cmd_mean, "png": cmd_png,
            "pair": cmd_pair, "boxcmp": cmd_boxcmp, "average": cmd_average, "exitance": cmd_exitance}
    if len(sys.argv) < 2 or sys.argv[1] not in cmds:
        sys.stderr.write(__doc__)
        sys.exit(2)
    cmds[sys.argv[1]](sys.argv[2:])

#!/usr/bin/env python3
"""An independent light tracer for the glass ball's transport (numpy; not part of the build or CI).

Photons leave the emitters of lamp-glass-floor3.json (the lamp) or floor-glass.json (the glowing
floor), cosine-distributed, pass the glass sphere with both Fresnel branches followed (weights, no
sampling) to depth 14, and land on the floor (y = 0) or ceiling (y = 548.8 mm) pieces, which reflect
them diffusely (reflectance 0.2) for `orders` bounces in all. Prints each piece's radiosity (red
channel) as JSON: compare with `penumbra solve` of the same scene.

  python3 light_trace_glass.py SCENE.json SEED [orders]

Measured 2026-12-05 (docs/final-gather.md): floor-glass, 4 x 3 M photons, 1 order; the solve at 1,024
paths a patch read the ceiling pieces +0.28 .. +0.51% high (these photons' standard error 0.08-0.18%).
"""
import json, sys
import numpy as np

scene = json.load(open(sys.argv[1]))
rng = np.random.default_rng(int(sys.argv[2]))
orders = int(sys.argv[3]) if len(sys.argv) > 3 else 5
mm = 1e-3
ceiling_y = 548.8 * mm
rho = 0.2
photons = 2_000_000


def rect(o):
    p = np.array(o["vertices"]) * mm
    return p[:, 0].min(), p[:, 0].max(), p[:, 2].min(), p[:, 2].max()


ball = next(o for o in scene["objects"] if o["type"] == "sphere")
centre, radius, ior = np.array(ball["center"]) * mm, ball["radius"] * mm, 1.5
pieces = {o["name"]: ((0.0, False) if o["name"].startswith("floor") else (ceiling_y, True), rect(o))
          for o in scene["objects"] if o["name"].startswith(("floor", "ceiling"))}


def hit_sphere(o, d, inside):
    oc = o - centre
    b = (oc * d).sum(1)
    disc = b * b - ((oc * oc).sum(1) - radius * radius)
    ok = disc > 0
    sq = np.sqrt(np.where(ok, disc, 0))
    if inside:
        return np.where(ok, -b + sq, np.inf)
    t = -b - sq
    return np.where(ok & (t > 1e-9), t, np.inf)


def fresnel(ci, e1, e2):
    st = e1 / e2 * np.sqrt(np.maximum(0, 1 - ci * ci))
    ct = np.sqrt(np.maximum(0, 1 - st * st))
    rs = (e1 * ci - e2 * ct) / (e1 * ci + e2 * ct)
    rp = (e2 * ci - e1 * ct) / (e2 * ci + e1 * ct)
    return np.where(st >= 1, 1.0, 0.5 * (rs * rs + rp * rp)), ct


def through(o, d, w):
    """The rays after the sphere: those that miss it, and every branch that leaves it."""
    t = hit_sphere(o, d, False)
    m = np.isfinite(t)
    out = [(o[~m], d[~m], w[~m])]
    o, d, w = o[m] + t[m, None] * d[m], d[m], w[m]
    inside = False
    for _ in range(14):
        n = (o - centre) / radius * (-1 if inside else 1)
        ci = -(d * n).sum(1)
        e1, e2 = (ior, 1.0) if inside else (1.0, ior)
        f, ct = fresnel(ci, e1, e2)
        reflected = d + 2 * ci[:, None] * n
        refracted = (e1 / e2) * d + ((e1 / e2) * ci - ct)[:, None] * n
        if inside:
            out.append((o, refracted, w * (1 - f)))
            w, d = w * f, reflected
        else:
            out.append((o, reflected, w * f))
            w, d, inside = w * (1 - f), refracted, True
        o = o + hit_sphere(o + 1e-9 * d, d, True)[:, None] * d
        keep = w > 1e-14
        o, d, w = o[keep], d[keep], w[keep]
    return out


power = {k: 0.0 for k in pieces}


def land(o, d, w, hits):
    for k, ((y, up), (x0, x1, z0, z1)) in pieces.items():
        m = d[:, 1] > 1e-12 if up else d[:, 1] < -1e-12
        q = o[m] + ((y - o[m, 1]) / d[m, 1])[:, None] * d[m]
        inside = (q[:, 0] >= x0) & (q[:, 0] <= x1) & (q[:, 2] >= z0) & (q[:, 2] <= z1)
        power[k] += w[m][inside].sum()
        hits.append((q[inside], w[m][inside], up))


def cosine(n, up):
    r1, r2 = rng.random(n), rng.random(n)
    r, phi = np.sqrt(r1), 2 * np.pi * r2
    return np.stack([r * np.cos(phi), (1 if up else -1) * np.sqrt(1 - r1), r * np.sin(phi)], 1)


lamp = [o for o in scene["objects"] if o["name"] == "light"]
hits = []
if lamp:  # the lamp, facing down, radiance L_e (red channel)
    x0, x1, z0, z1 = rect(lamp[0])
    le = scene["materials"][lamp[0]["material"]]["emission"][0]
    p = np.stack([x0 + (x1 - x0) * rng.random(photons), np.full(photons, ceiling_y),
                  z0 + (z1 - z0) * rng.random(photons)], 1)
    w = np.full(photons, np.pi * le * (x1 - x0) * (z1 - z0) / photons)
    for o, d, ww in through(p, cosine(photons, False), w):
        land(o, d, ww, hits)
else:  # the glowing floor quarters, L_e = 1
    for k, ((y, up), (x0, x1, z0, z1)) in pieces.items():
        if up:
            continue
        n = photons // 4
        p = np.stack([x0 + (x1 - x0) * rng.random(n), np.zeros(n), z0 + (z1 - z0) * rng.random(n)], 1)
        hits.append((p, np.full(n, np.pi * (x1 - x0) * (z1 - z0) / n) / rho, False))
        # (divided by rho: the bounce below multiplies it back; the floor itself is black)
    orders += 1
for _ in range(orders - 1):
    new = []
    for q, w, up in hits:
        if len(q):
            for o, d, ww in through(q + (-1e-7 if up else 1e-7) * np.array([0, 1, 0]), cosine(len(q), not up), w * rho):
                land(o, d, ww, new)
    hits = new
area = {k: (r[1] - r[0]) * (r[3] - r[2]) for k, (_, r) in pieces.items()}
print(json.dumps({k: rho * power[k] / area[k] for k in pieces if lamp or k.startswith("ceiling")}))

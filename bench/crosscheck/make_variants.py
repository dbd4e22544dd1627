#!/usr/bin/env python3
"""Scenes made from scenes/cornell-glass.json to find where the solve and the path tracer part
(docs/final-gather.md, "The balls in the solve's geometry"). Writes them into the folder given
(default: the current one). Standard library only.

  cg-split       the floor cut in four quarters (floor_glass under the glass ball, floor_mirror
                 under the mirror ball, floor_b and floor_c)
  cg-raised      the same, both balls 5 cm higher
  cgr-mirror     cg-raised without the glass ball
  cgr-glass      cg-raised without the mirror ball
  lamp-glass-floor3  the lamp (black), the ceiling pieces and the floor quarters at reflectance 0.2,
                 the raised glass ball: light_trace_glass.py's scene
  floor-glass    the same with the floor glowing (L_e = 1, black) and no lamp
"""
import copy, json, os, sys

here = os.path.dirname(os.path.abspath(__file__))
out = sys.argv[1] if len(sys.argv) > 1 else "."
os.makedirs(out, exist_ok=True)
base = json.load(open(os.path.join(here, "..", "..", "scenes", "cornell-glass.json")))


def write(name, scene):
    with open(os.path.join(out, name + ".json"), "w") as f:
        json.dump(scene, f, indent=1)


def quarters(scene):
    xe0, xe1, xm = 552.8, 551.198, 282.0  # the floor's slanted right edge at z = 0, 280

    def quad(name, x0, x1a, x1b, z0, z1):
        return {"name": name, "type": "quad", "material": "white",
                "vertices": [[x1a, 0, z0], [x0, 0, z0], [x0, 0, z1], [x1b, 0, z1]]}
    parts = [quad("floor_glass", 0, xm, xm, 0, 280), quad("floor_b", xm, xe0, xe1, 0, 280),
             quad("floor_c", 0, xm, xm, 280, 559.2), quad("floor_mirror", xm, xe1, 549.6, 280, 559.2)]
    s = copy.deepcopy(scene)
    s["objects"] = [p for o in scene["objects"] for p in (parts if o["name"] == "floor" else [o])]
    return s


split = quarters(base)
write("cg-split", split)
raised = copy.deepcopy(split)
for o in raised["objects"]:
    if o["name"] in ("mirror_ball", "glass_ball"):
        o["center"][1] = 150.5
write("cg-raised", raised)
for name, drop in (("cgr-mirror", "glass_ball"), ("cgr-glass", "mirror_ball")):
    s = copy.deepcopy(raised)
    s["objects"] = [o for o in s["objects"] if o["name"] != drop]
    write(name, s)
keep = ("light", "ceiling_front", "ceiling_back", "ceiling_left", "ceiling_right", "glass_ball",
        "floor_glass", "floor_b", "floor_c", "floor_mirror")
s = copy.deepcopy(raised)
s["objects"] = [o for o in s["objects"] if o["name"] in keep]
s["materials"]["dim"] = {"type": "diffuse", "reflectance": [0.2, 0.2, 0.2]}
s["materials"]["lamp"]["reflectance"] = [0, 0, 0]
for o in s["objects"]:
    if o["name"].startswith(("ceiling", "floor")):
        o["material"] = "dim"
write("lamp-glass-floor3", s)
s = copy.deepcopy(s)
s["materials"]["glow"] = {"type": "diffuse", "reflectance": [0, 0, 0], "emission": [1, 1, 1]}
s["objects"] = [o for o in s["objects"] if o["name"] != "light"]
for o in s["objects"]:
    if o["name"].startswith("floor"):
        o["material"] = "glow"
write("floor-glass", s)

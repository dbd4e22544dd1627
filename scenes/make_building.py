#!/usr/bin/env python3
"""Generate the office-building scenes of Penumbra.

What it makes: one storey of an office building (metres, y up, x along the
corridor, z across it).  A straight corridor, 2.4 m wide and 2.7 m high, runs
from a closed end at x = 0 to an open end (no end wall: light escapes there).
Offices of 4 x 5 m line both sides, each joined to the corridor by a door
opening of 0.9 x 2.1 m with its leaf standing ajar.  The rooms hold desks
(top, legs, modesty panel, drawer pedestal, monitor, keyboard, a few books),
chairs (seat, legs, back posts, backrest), filing cabinets, meeting tables,
whiteboards and bookshelves (sides, top, back panel, plinth, shelf boards,
books, binders and lying stacks as thin boxes).  Small emissive quads
1 cm below the ceiling light the rooms and the corridor.

Two files are written by the same code:

  scenes/building.json           walls, floor and ceiling are solid boxes
                                 (walls 0.1 m thick): the scene is the
                                 boundary of those solids, so both sides of
                                 every wall are front faces, doors are
                                 openings through the thick wall with reveal
                                 faces, and the building has an outside.
  scenes/building-one-sided.json the same inside surfaces only: every wall
                                 is one quad (split around its door) facing
                                 the room it bounds; a wall between two rooms
                                 is one quad per room at the wall's two
                                 faces, 0.1 m apart.  No outside faces.

Furniture is the same in both.  Every box of furniture is closed and faces
outward, except that a face resting flat against another surface (a bottom on
the floor, a leg's top under a desk top, a board's end against a shelf side,
a book's bottom on a board) is left out: it would be coplanar with that
surface and overlap it.  The script checks its own output (planarity,
winding, unique names, no coplanar overlapping faces, no boxes sunk into one
another, furniture inside its room and on the floor, every left-out face
covered) and prints the quad counts.  The output is deterministic.

Run from the project root:

    python3 scenes/make_building.py
"""

import json
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

# --- dimensions (metres) -----------------------------------------------------
WALL = 0.10               # wall thickness
HEIGHT = 2.70             # floor to ceiling
SLAB = 0.20               # floor and ceiling slab thickness (two-sided variant)
CORR_HALF = 1.20          # half the corridor width
ROOM_W = 4.00             # room size along the corridor (x)
ROOM_D = 5.00             # room size across it (z)
ROOMS_PER_SIDE = 9
PITCH = ROOM_W + WALL
LENGTH = round(WALL + ROOMS_PER_SIDE * PITCH, 6)  # x of the open end
Z_ROOM = CORR_HALF + WALL                         # room face of corridor wall
Z_EXT = Z_ROOM + ROOM_D                           # inner face of outer wall
Z_OUT = Z_EXT + WALL                              # outer face of outer wall
DOOR_W, DOOR_H = 0.90, 2.10
DOOR_U = 0.50             # door's distance from the room's left-hand wall
LAMP = 0.60               # lamp edge
LAMP_DROP = 0.01          # lamps hang this far below the ceiling
CORRIDOR_LAMP_STEP = 4.5

MATERIALS = {
    "wall":          {"type": "diffuse", "reflectance": [0.76, 0.76, 0.74]},
    "wall_corridor": {"type": "diffuse", "reflectance": [0.72, 0.74, 0.70]},
    "ceiling":       {"type": "diffuse", "reflectance": [0.80, 0.80, 0.80]},
    "floor":         {"type": "diffuse", "reflectance": [0.45, 0.45, 0.45]},
    "floor_corridor": {"type": "diffuse", "reflectance": [0.40, 0.41, 0.43]},
    "facade":        {"type": "diffuse", "reflectance": [0.50, 0.50, 0.50]},
    "roof":          {"type": "diffuse", "reflectance": [0.30, 0.30, 0.30]},
    "lamp":          {"type": "diffuse", "reflectance": [0.5, 0.5, 0.5],
                      "emission": [8.0, 8.0, 8.0]},
    "wood":          {"type": "diffuse", "reflectance": [0.50, 0.35, 0.20]},
    "wood_light":    {"type": "diffuse", "reflectance": [0.62, 0.48, 0.30]},
    "door":          {"type": "diffuse", "reflectance": [0.55, 0.40, 0.26]},
    "metal":         {"type": "diffuse", "reflectance": [0.55, 0.55, 0.58]},
    "cabinet":       {"type": "diffuse", "reflectance": [0.62, 0.63, 0.65]},
    "plastic_dark":  {"type": "diffuse", "reflectance": [0.10, 0.10, 0.11]},
    "screen":        {"type": "diffuse", "reflectance": [0.03, 0.03, 0.04]},
    "whiteboard":    {"type": "diffuse", "reflectance": [0.85, 0.85, 0.85]},
    "chair_blue":    {"type": "diffuse", "reflectance": [0.12, 0.22, 0.55]},
    "chair_red":     {"type": "diffuse", "reflectance": [0.60, 0.12, 0.10]},
    "chair_green":   {"type": "diffuse", "reflectance": [0.18, 0.45, 0.22]},
    "chair_orange":  {"type": "diffuse", "reflectance": [0.70, 0.40, 0.10]},
    "book_red":      {"type": "diffuse", "reflectance": [0.55, 0.10, 0.08]},
    "book_blue":     {"type": "diffuse", "reflectance": [0.10, 0.18, 0.45]},
    "book_green":    {"type": "diffuse", "reflectance": [0.12, 0.35, 0.15]},
    "book_ochre":    {"type": "diffuse", "reflectance": [0.65, 0.50, 0.15]},
    "book_cream":    {"type": "diffuse", "reflectance": [0.75, 0.70, 0.58]},
    "book_black":    {"type": "diffuse", "reflectance": [0.06, 0.06, 0.06]},
}
CHAIR_COLOURS = ["chair_blue", "chair_red", "chair_green", "chair_orange"]
BOOK_COLOURS = ["book_red", "book_blue", "book_green", "book_ochre",
                "book_cream", "book_black"]
BINDER_COLOURS = ["book_blue", "book_black", "book_red", "book_cream"]

EPS = 1e-7


class Rng:
    """A tiny explicit LCG, so that the output never depends on the Python
    version's random module."""

    def __init__(self, seed):
        self.state = seed & 0xFFFFFFFFFFFFFFFF

    def random(self):
        self.state = (6364136223846793005 * self.state
                      + 1442695040888963407) & 0xFFFFFFFFFFFFFFFF
        return (self.state >> 11) / float(1 << 53)

    def uniform(self, a, b):
        return a + (b - a) * self.random()

    def choice(self, seq):
        return seq[int(self.random() * len(seq)) % len(seq)]


# --- vector helpers ----------------------------------------------------------
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def mean(points):
    n = float(len(points))
    return tuple(sum(p[k] for p in points) / n for k in range(3))


def quad_normal(v):
    return cross(sub(v[1], v[0]), sub(v[2], v[0]))


class Frame:
    """A placement in the horizontal plane: local (a, y, b) -> world (x, y, z)
    with (x, z) = M (a, b) + t.  M is a rotation (det +1), so a right-handed
    local box stays right-handed."""

    def __init__(self, m=(1.0, 0.0, 0.0, 1.0), t=(0.0, 0.0), aligned=True,
                 key="world"):
        self.m, self.t, self.aligned, self.key = m, t, aligned, key

    def __call__(self, p):
        a, y, b = p
        m = self.m
        return (m[0] * a + m[1] * b + self.t[0], y,
                m[2] * a + m[3] * b + self.t[1])

    def sub(self, u, w, deg=0.0, key=None):
        """The frame with its origin at local (u, w) and its a axis turned by
        deg degrees from this frame's a axis towards its b axis."""
        c = round(math.cos(math.radians(deg)), 12)
        s = round(math.sin(math.radians(deg)), 12)
        r = (c, -s, s, c)
        m = self.m
        mm = (m[0] * r[0] + m[1] * r[2], m[0] * r[1] + m[1] * r[3],
              m[2] * r[0] + m[3] * r[2], m[2] * r[1] + m[3] * r[3])
        x, _, z = self((u, 0.0, w))
        aligned = self.aligned and abs(deg / 90.0 - round(deg / 90.0)) < 1e-9
        return Frame(mm, (x, z), aligned, key or self.key)


class Scene:
    """Collects the quads, and what the self-check needs."""

    def __init__(self, one_sided):
        self.one_sided = one_sided
        self.objects = []      # (name, material, 4 vertices)
        self.names = set()
        self.omitted = []      # (name, 4 vertices, facing) of left-out faces
        self.boxes = []        # (room, item, frame, lo, hi, world aabb)
        self.items = []        # (room, item, on_floor)
        self.counters = {}

    def count(self, key):
        n = self.counters.get(key, 0)
        self.counters[key] = n + 1
        return n


def rnd(v):
    return round(v, 5) + 0.0     # + 0.0 turns -0.0 into 0.0


def quad(sc, name, material, verts, facing):
    """Add a quad; its vertices are put counter-clockwise seen from the side
    `facing` points to (the front face)."""
    v = [tuple(rnd(c) for c in p) for p in verts]
    if dot(quad_normal(v), facing) < 0.0:
        v.reverse()
    if name in sc.names:
        raise ValueError("duplicate object name " + name)
    if material not in MATERIALS:
        raise ValueError("unknown material " + material)
    sc.names.add(name)
    sc.objects.append((name, material, v))


FACES = (("nx", 0, 0), ("px", 0, 1), ("ny", 1, 0), ("py", 1, 1),
         ("nz", 2, 0), ("pz", 2, 1))


def box(sc, name, material, frame, lo, hi, omit=(), mats=None, room=None,
        item=None):
    """A box from local corner lo to hi (a, y, b) in `frame`, with its faces
    pointing outward.  Faces named in `omit` ("nx", "py", ...: the local axis
    and side) rest against another surface and are left out.  `mats`
    overrides the material of single faces."""
    centre = frame(mean([lo, hi]))
    corners = []
    for tag, axis, side in FACES:
        i, j = [k for k in range(3) if k != axis]
        pts = []
        for a, b in ((lo[i], lo[j]), (hi[i], lo[j]), (hi[i], hi[j]),
                     (lo[i], hi[j])):
            p = [0.0, 0.0, 0.0]
            p[axis] = hi[axis] if side else lo[axis]
            p[i], p[j] = a, b
            pts.append(frame(p))
        corners.extend(pts)
        facing = sub(mean(pts), centre)
        if tag in omit:
            sc.omitted.append((name + "_" + tag,
                               [tuple(rnd(c) for c in p) for p in pts],
                               facing))
            continue
        quad(sc, name + "_" + tag, (mats or {}).get(tag, material), pts,
             facing)
    aabb = (tuple(min(p[k] for p in corners) for k in range(3)),
            tuple(max(p[k] for p in corners) for k in range(3)))
    sc.boxes.append((room, item or name, frame, lo, hi, aabb))


def item(sc, room, name, on_floor=True):
    sc.items.append((room, name, on_floor))
    return name


# --- the building's solid structure -----------------------------------------
def rooms():
    """Every office: name, side, x of its left-hand end, frame, world extent
    and door opening.  A room's frame has u (a) along its corridor wall, w (b)
    from the corridor wall (w = 0) to the outer wall (w = ROOM_D); the door
    is at u in [DOOR_U, DOOR_U + DOOR_W] as seen from inside."""
    out = []
    for side in ("n", "s"):
        for i in range(ROOMS_PER_SIDE):
            r = i if side == "n" else ROOMS_PER_SIDE + i
            x0 = round(WALL + i * PITCH, 6)
            if side == "n":
                frame = Frame((1.0, 0.0, 0.0, 1.0), (x0, Z_ROOM), True,
                              "room%02d" % r)
                lo, hi = (x0, 0.0, Z_ROOM), (x0 + ROOM_W, HEIGHT, Z_EXT)
                door_x = x0 + DOOR_U
                door_z = (CORR_HALF, Z_ROOM)
            else:   # turned by 180 degrees: its door is at the other end
                frame = Frame((-1.0, 0.0, 0.0, -1.0), (x0 + ROOM_W, -Z_ROOM),
                              True, "room%02d" % r)
                lo, hi = (x0, 0.0, -Z_EXT), (x0 + ROOM_W, HEIGHT, -Z_ROOM)
                door_x = x0 + ROOM_W - DOOR_U - DOOR_W
                door_z = (-Z_ROOM, -CORR_HALF)
            out.append({"name": "room%02d" % r, "index": r, "side": side,
                        "frame": frame, "lo": lo,
                        "hi": tuple(round(c, 6) for c in hi),
                        "door": (round(door_x, 6), round(door_x + DOOR_W, 6),
                                 door_z)})
    return out


def shell_boxes():
    """End walls, outer walls, room partitions and the two slabs."""
    b = [((0.0, 0.0, -Z_OUT), (WALL, HEIGHT, Z_OUT)),          # closed end
         ((WALL, 0.0, Z_EXT), (LENGTH, HEIGHT, Z_OUT)),        # outer walls
         ((WALL, 0.0, -Z_OUT), (LENGTH, HEIGHT, -Z_EXT)),
         ((LENGTH - WALL, 0.0, Z_ROOM), (LENGTH, HEIGHT, Z_EXT)),  # last
         ((LENGTH - WALL, 0.0, -Z_EXT), (LENGTH, HEIGHT, -Z_ROOM)),  # rooms
         ((0.0, -SLAB, -Z_OUT), (LENGTH, 0.0, Z_OUT)),          # floor slab
         ((0.0, HEIGHT, -Z_OUT), (LENGTH, HEIGHT + SLAB, Z_OUT))]  # ceiling
    for k in range(1, ROOMS_PER_SIDE):
        x = k * PITCH
        b.append(((x, 0.0, Z_ROOM), (x + WALL, HEIGHT, Z_EXT)))
        b.append(((x, 0.0, -Z_EXT), (x + WALL, HEIGHT, -Z_ROOM)))
    return b


def corridor(room_list):
    """The corridor's two walls, cut by the door openings (wall pieces
    between the doors and a lintel over each door, as solid boxes), and
    where its lamps go (one every CORRIDOR_LAMP_STEP)."""
    boxes = []
    for side, (z0, z1) in (("n", (CORR_HALF, Z_ROOM)),
                           ("s", (-Z_ROOM, -CORR_HALF))):
        doors = sorted(r["door"][:2] for r in room_list if r["side"] == side)
        x = WALL
        for d0, d1 in doors:
            boxes.append(((x, 0.0, z0), (d0, HEIGHT, z1)))
            boxes.append(((d0, DOOR_H, z0), (d1, HEIGHT, z1)))   # lintel
            x = d1
        boxes.append(((x, 0.0, z0), (LENGTH, HEIGHT, z1)))
    lamps = []
    x = 2.3
    while x < LENGTH - 1.0:
        lamps.append((x, 0.0))
        x += CORRIDOR_LAMP_STEP
    return boxes, lamps


def lamp(sc, name, x, z):
    y = HEIGHT - LAMP_DROP
    h = LAMP / 2.0
    quad(sc, name, "lamp", [(x - h, y, z - h), (x + h, y, z - h),
                            (x + h, y, z + h), (x - h, y, z + h)],
         (0.0, -1.0, 0.0))


def region_of(p, room_list):
    """Which free space a point is in: a room, a door opening, the corridor
    or the outside."""
    x, y, z = p
    if not (0.0 < y < HEIGHT):
        return "outside"
    if WALL < x < LENGTH and -CORR_HALF < z < CORR_HALF:
        return "corridor"
    for r in room_list:
        lo, hi = r["lo"], r["hi"]
        if lo[0] < x < hi[0] and lo[2] < z < hi[2]:
            return r["name"]
        d0, d1, (z0, z1) = r["door"]
        if d0 < x < d1 and z0 < z < z1 and y < DOOR_H:
            return r["name"] + "_door"
    return "outside"


def rect_difference(rect, covers, label):
    """The rectangle (u0, u1, v0, v1) minus the union of `covers`, as
    rectangles: the grid of all their edges, its free cells merged greedily
    (along u, then v) while they have the same label(u, v) (the free space
    they face), so that e.g. a door's threshold stays apart from the room's
    floor."""
    u0, u1, v0, v1 = rect
    us = sorted({u0, u1} | {c for r in covers for c in r[:2] if u0 < c < u1})
    vs = sorted({v0, v1} | {c for r in covers for c in r[2:] if v0 < c < v1})
    cell = []
    for j in range(len(vs) - 1):
        row = []
        for i in range(len(us) - 1):
            u, v = (us[i] + us[i + 1]) / 2, (vs[j] + vs[j + 1]) / 2
            covered = any(r[0] <= u <= r[1] and r[2] <= v <= r[3]
                          for r in covers)
            row.append(None if covered else label(u, v))
        cell.append(row)
    out = []
    for j in range(len(vs) - 1):
        for i in range(len(us) - 1):
            lab = cell[j][i]
            if lab is None:
                continue
            i1 = i
            while i1 + 1 < len(us) - 1 and cell[j][i1 + 1] == lab:
                i1 += 1
            j1 = j
            while j1 + 1 < len(vs) - 1 and all(cell[j1 + 1][k] == lab
                                               for k in range(i, i1 + 1)):
                j1 += 1
            for jj in range(j, j1 + 1):
                for ii in range(i, i1 + 1):
                    cell[jj][ii] = None
            out.append((us[i], us[i1 + 1], vs[j], vs[j1 + 1], lab))
    return out


def solid_faces(sc, solids, room_list):
    """Emit the boundary of the union of the solid boxes (which touch but do
    not overlap): each box face minus where another box rests against it.
    Faces are named and coloured by the free space in front of them; in the
    one-sided variant the faces towards the outside are left out."""
    solids = [(tuple(round(c, 6) for c in lo), tuple(round(c, 6) for c in hi))
              for lo, hi in solids]
    for bi, (lo, hi) in enumerate(solids):
        for tag, axis, side in FACES:
            i, j = [k for k in range(3) if k != axis]
            c = hi[axis] if side else lo[axis]
            rect = (lo[i], hi[i], lo[j], hi[j])
            covers = []
            for bj, (lo2, hi2) in enumerate(solids):
                c2 = lo2[axis] if side else hi2[axis]
                if bj == bi or abs(c2 - c) > EPS:
                    continue
                r = (max(rect[0], lo2[i]), min(rect[1], hi2[i]),
                     max(rect[2], lo2[j]), min(rect[3], hi2[j]))
                if r[1] - r[0] > EPS and r[3] - r[2] > EPS:
                    covers.append(r)
            normal = [0.0, 0.0, 0.0]
            normal[axis] = 1.0 if side else -1.0

            def point(a, b):
                p = [0.0, 0.0, 0.0]
                p[axis], p[i], p[j] = c, a, b
                return tuple(p)

            def label(a, b):
                p = point(a, b)
                return region_of(tuple(p[k] + 0.005 * normal[k]
                                       for k in range(3)), room_list)

            for ru0, ru1, rv0, rv1, reg in rect_difference(rect, covers,
                                                           label):
                pts = [point(a, b) for a, b in ((ru0, rv0), (ru1, rv0),
                                                (ru1, rv1), (ru0, rv1))]
                if reg == "outside":
                    if sc.one_sided:
                        continue
                    kind, mat = {1.0: ("roof", "roof")}.get(
                        normal[1], ("facade", "facade"))
                elif reg.endswith("_door"):
                    kind, mat = ("floor", "floor") if normal[1] > 0 else (
                        "reveal", "wall")
                elif normal[1] > 0:
                    kind, mat = "floor", ("floor_corridor"
                                          if reg == "corridor" else "floor")
                elif normal[1] < 0:
                    kind, mat = "ceiling", "ceiling"
                else:
                    kind, mat = "wall", ("wall_corridor"
                                         if reg == "corridor" else "wall")
                name = "%s_%s%d" % (reg, kind, sc.count((reg, kind)))
                quad(sc, name, mat, pts, tuple(normal))


# --- furniture ---------------------------------------------------------------
# Each piece is built in its own frame: a along its width, y up, b from its
# front (b = 0) to its back; the back is the side that goes against a wall.
def against(room_frame, wall, start, width, depth, gap):
    """The frame of a piece `width` wide and `depth` deep standing with its
    back `gap` from one of the room's walls ("left" u = 0, "right" u =
    ROOM_W, "back" w = ROOM_D, "front" w = 0); `start` is where it begins
    along that wall (lowest u or w)."""
    if wall == "back":
        return room_frame.sub(start, ROOM_D - gap - depth, 0.0)
    if wall == "left":
        return room_frame.sub(gap + depth, start, 90.0)
    if wall == "right":
        return room_frame.sub(ROOM_W - gap - depth, start + width, -90.0)
    if wall == "front":
        return room_frame.sub(start + width, gap + depth, 180.0)
    raise ValueError(wall)


def desk(sc, room, name, frame, rng, width=1.6, depth=0.8, pedestal=True,
         monitor=True):
    """A desk: a top slab on four legs, a modesty panel at the back, a drawer
    pedestal with three drawers, a monitor and a keyboard."""
    n = item(sc, room, "%s_%s" % (room, name))
    kw = {"room": room, "item": n}
    top_lo, top_hi = 0.72, 0.75
    box(sc, n + "_top", "wood", frame, (0, top_lo, 0), (width, top_hi, depth),
        **kw)
    for k, (a, b) in enumerate(((0.03, 0.03), (width - 0.08, 0.03),
                                (0.03, depth - 0.08),
                                (width - 0.08, depth - 0.08))):
        box(sc, "%s_leg%d" % (n, k), "metal", frame, (a, 0, b),
            (a + 0.05, top_lo, b + 0.05), omit=("ny", "py"), **kw)
    box(sc, n + "_panel", "wood", frame, (0.08, 0.30, depth - 0.065),
        (width - 0.08, top_lo, depth - 0.045), omit=("nx", "px", "py"), **kw)
    if pedestal:
        p0, p1 = width - 0.55, width - 0.12
        box(sc, n + "_pedestal", "wood", frame, (p0, 0, 0.05),
            (p1, top_lo, depth - 0.10), omit=("ny", "py"), **kw)
        for k, (y0, y1) in enumerate(((0.03, 0.25), (0.26, 0.48),
                                      (0.49, 0.70))):
            box(sc, "%s_drawer%d" % (n, k), "wood_light", frame,
                (p0 + 0.01, y0, 0.03), (p1 - 0.01, y1, 0.05), omit=("pz",),
                **kw)
    if monitor:
        c = 0.6
        box(sc, n + "_monitor_base", "plastic_dark", frame,
            (c - 0.1, top_hi, 0.45), (c + 0.1, top_hi + 0.01, 0.65),
            omit=("ny",), **kw)
        box(sc, n + "_monitor_neck", "plastic_dark", frame,
            (c - 0.02, top_hi + 0.01, 0.515), (c + 0.02, 0.92, 0.545),
            omit=("ny", "py"), **kw)
        box(sc, n + "_monitor", "plastic_dark", frame,
            (c - 0.27, 0.92, 0.50), (c + 0.27, 1.25, 0.56),
            mats={"nz": "screen"}, **kw)
        box(sc, n + "_keyboard", "plastic_dark", frame,
            (c - 0.22, top_hi, 0.15), (c + 0.22, top_hi + 0.02, 0.30),
            omit=("ny",), **kw)
    # a few books lying on the desk, each smaller than the one below it
    y = top_hi
    a0, b0, sa, sb = width - 0.45, 0.25, 0.26, 0.20
    for k in range(int(rng.uniform(1, 4))):
        h = rng.uniform(0.02, 0.045)
        box(sc, "%s_book%d" % (n, k), rng.choice(BOOK_COLOURS), frame,
            (a0, y, b0), (a0 + sa, y + h, b0 + sb), omit=("ny",), **kw)
        y += h
        a0, b0 = a0 + 0.01, b0 + 0.01
        sa, sb = sa - rng.uniform(0.02, 0.05), sb - rng.uniform(0.02, 0.04)


def table(sc, room, name, frame, width, depth):
    """A meeting table: a top slab on four legs."""
    n = item(sc, room, "%s_%s" % (room, name))
    kw = {"room": room, "item": n}
    box(sc, n + "_top", "wood", frame, (0, 0.72, 0), (width, 0.75, depth),
        **kw)
    for k, (a, b) in enumerate(((0.05, 0.05), (width - 0.11, 0.05),
                                (0.05, depth - 0.11),
                                (width - 0.11, depth - 0.11))):
        box(sc, "%s_leg%d" % (n, k), "wood", frame, (a, 0, b),
            (a + 0.06, 0.72, b + 0.06), omit=("ny", "py"), **kw)


def chair(sc, room, name, frame, colour):
    """A chair in a frame centred on its seat, its back towards +b: seat,
    four legs, two back posts and a backrest."""
    n = item(sc, room, "%s_%s" % (room, name))
    kw = {"room": room, "item": n}
    s, y0, y1 = 0.23, 0.43, 0.48
    box(sc, n + "_seat", colour, frame, (-s, y0, -s), (s, y1, s), **kw)
    for k, (a, b) in enumerate(((-0.22, -0.22), (0.19, -0.22), (-0.22, 0.19),
                                (0.19, 0.19))):
        box(sc, "%s_leg%d" % (n, k), "metal", frame, (a, 0, b),
            (a + 0.03, y0, b + 0.03), omit=("ny", "py"), **kw)
    for k, a in enumerate((-0.22, 0.19)):
        box(sc, "%s_post%d" % (n, k), "metal", frame, (a, y1, 0.19),
            (a + 0.03, 0.95, 0.22), omit=("ny",), **kw)
    box(sc, n + "_back", colour, frame, (-0.19, 0.62, 0.195),
        (0.19, 0.92, 0.215), omit=("nx", "px"), **kw)


def cabinet(sc, room, name, frame):
    """A filing cabinet 0.45 wide, 0.6 deep, 1.32 high with four drawers."""
    n = item(sc, room, "%s_%s" % (room, name))
    kw = {"room": room, "item": n}
    w, d, h = 0.45, 0.60, 1.32
    box(sc, n + "_body", "cabinet", frame, (0, 0, 0.02), (w, h, d),
        omit=("ny",), **kw)
    for k in range(4):
        y0 = 0.02 + k * 0.325
        y1 = y0 + 0.31
        box(sc, "%s_drawer%d" % (n, k), "cabinet", frame, (0.01, y0, 0),
            (w - 0.01, y1, 0.02), omit=("pz",), **kw)
        box(sc, "%s_handle%d" % (n, k), "metal", frame,
            (w / 2 - 0.07, y1 - 0.06, -0.02), (w / 2 + 0.07, y1 - 0.04, 0),
            omit=("pz",), **kw)


def whiteboard(sc, room, name, frame, width):
    """A whiteboard hanging on a wall (its back against the wall) with a
    marker tray below it."""
    n = item(sc, room, "%s_%s" % (room, name), on_floor=False)
    kw = {"room": room, "item": n}
    box(sc, n + "_board", "whiteboard", frame, (0, 0.9, 0.0),
        (width, 2.1, 0.02), omit=("pz",), mats={"px": "metal", "nx": "metal",
                                                "py": "metal", "ny": "metal"},
        **kw)
    box(sc, n + "_tray", "metal", frame, (0.2, 0.92, -0.06),
        (width - 0.2, 0.95, 0.0), omit=("pz",), **kw)


SHELF_W, SHELF_D = 0.90, 0.35
SHELF_T = 0.02                     # board thickness
SHELF_PLINTH = 0.08
TALL, LOW = (2.00, 5), (1.10, 2)   # (height, shelf boards) of the two sizes


def bookshelf(sc, room, name, frame, rng, size=TALL, fill=0.8):
    """A bookshelf: two sides, a top, a back panel, a plinth and shelf
    boards; the compartments hold books, binders and lying stacks."""
    n = item(sc, room, "%s_%s" % (room, name))
    kw = {"room": room, "item": n}
    (h, boards), w, d, t = size, SHELF_W, SHELF_D, SHELF_T
    inner_top = h - t
    for k, a in enumerate((0.0, w - t)):
        box(sc, "%s_side%d" % (n, k), "wood_light", frame, (a, 0, 0),
            (a + t, inner_top, d), omit=("ny", "py"), **kw)
    box(sc, n + "_top", "wood_light", frame, (0, inner_top, 0), (w, h, d),
        **kw)
    box(sc, n + "_backpanel", "wood_light", frame, (t, 0, d - 0.01),
        (w - t, inner_top, d), omit=("nx", "px", "ny", "py"), **kw)
    box(sc, n + "_plinth", "wood_light", frame, (t, 0, 0.02),
        (w - t, SHELF_PLINTH, d - 0.01), omit=("nx", "px", "ny", "pz"), **kw)
    clear = (inner_top - SHELF_PLINTH - boards * t) / (boards + 1)
    floors = [SHELF_PLINTH]
    for k in range(boards):
        y0 = SHELF_PLINTH + (k + 1) * clear + k * t
        box(sc, "%s_board%d" % (n, k), "wood_light", frame, (t, y0, 0),
            (w - t, y0 + t, d - 0.01), omit=("nx", "px", "pz"), **kw)
        floors.append(y0 + t)
    nb = 0
    for f in floors:
        if rng.random() < fill:
            nb = compartment(sc, n, frame, rng, f, clear, nb, kw)


def compartment(sc, n, frame, rng, floor_y, clear, nb, kw):
    """One compartment of a shelf: a row of standing books (or binders) from
    the left, sometimes a lying stack at the right, each book standing on
    the board with a gap to its neighbours and to the back panel."""
    a_lo, a_hi = SHELF_T + 0.004, SHELF_W - SHELF_T - 0.004
    back = SHELF_D - 0.01 - 0.015
    binders = rng.random() < 0.25
    count = int(rng.uniform(3, 6) if binders else rng.uniform(3, 10))
    a = a_lo if rng.random() < 0.7 else a_lo + rng.uniform(0.05, 0.25)
    for _ in range(count):
        if binders:
            wd, ht, dp = rng.uniform(0.06, 0.08), clear - 0.035, 0.28
            mat = rng.choice(BINDER_COLOURS)
        else:
            wd = rng.uniform(0.022, 0.05)
            ht = rng.uniform(0.17, min(0.29, clear - 0.025))
            dp = rng.uniform(0.14, 0.23)
            mat = rng.choice(BOOK_COLOURS)
        if a + wd > a_hi:
            break
        box(sc, "%s_book%03d" % (n, nb), mat, frame, (a, floor_y, back - dp),
            (a + wd, floor_y + ht, back), omit=("ny",), **kw)
        nb += 1
        a += wd + 0.003
    if a_hi - a > 0.27 and rng.random() < 0.35:     # a lying stack
        y = floor_y
        sa, sb = rng.uniform(0.2, 0.24), rng.uniform(0.15, 0.2)
        a0 = a_hi - sa - 0.01
        b0 = back - sb - 0.01
        for k in range(int(rng.uniform(2, 4))):
            ht = rng.uniform(0.025, 0.045)
            box(sc, "%s_book%03d" % (n, nb), rng.choice(BOOK_COLOURS), frame,
                (a0, y, b0), (a0 + sa, y + ht, b0 + sb), omit=("ny",), **kw)
            nb += 1
            y += ht
            da, db = rng.uniform(0.005, 0.02), rng.uniform(0.005, 0.02)
            a0, b0 = a0 + da, b0 + db
            sa, sb = sa - 2 * da, sb - 2 * db
    return nb


def door_leaf(sc, room, frame):
    """The door leaf standing ajar: hinged at the door's left jamb on the
    room side, opened by 75 degrees into the room, a handle on each face."""
    n = item(sc, room, room + "_doorleaf", on_floor=False)
    kw = {"room": room, "item": n}
    f = frame.sub(DOOR_U + 0.045, 0.005, 75.0, key=n)
    lw = DOOR_W - 0.02
    box(sc, n, "door", f, (0, 0.01, 0), (lw, DOOR_H - 0.015, 0.04), **kw)
    for k, (b0, b1, om) in enumerate(((-0.06, 0.0, "pz"),
                                      (0.04, 0.10, "nz"))):
        box(sc, "%s_handle%d" % (n, k), "metal", f, (lw - 0.16, 1.0, b0),
            (lw - 0.05, 1.03, b1), omit=(om,), **kw)


def room(sc, r, rng):
    """Furnish one office.  Three layouts take turns: a two-person office, a
    meeting room and a small library.  The door's swing (u < 1.6, w < 1.1)
    is kept clear."""
    f, name, kind = r["frame"], r["name"], r["index"] % 3
    door_leaf(sc, name, f)
    colour = CHAIR_COLOURS[r["index"] % len(CHAIR_COLOURS)]

    def chair_at(label, u, w, deg, twist):
        chair(sc, name, label, f.sub(u, w, deg + twist, key=name + label),
              colour)

    if kind == 0:                                   # two-person office
        for k, u0 in enumerate((0.3, 2.1)):
            desk(sc, name, "desk%d" % k, against(f, "back", u0, 1.6, 0.8,
                                                 0.05), rng)
        chair_at("chair0", 1.1, 3.6, 180.0, 12.0)
        chair_at("chair1", 2.9, 3.55, 180.0, -9.0)
        bookshelf(sc, name, "shelf0",
                  against(f, "right", 1.6, SHELF_W, SHELF_D, 0.01), rng)
        cabinet(sc, name, "cabinet0", against(f, "left", 2.0, 0.45, 0.6,
                                              0.02))
        lamps = ((1.1, 3.0), (2.9, 3.0))
    elif kind == 1:                                 # meeting room
        table(sc, name, "table", f.sub(1.0, 2.1), 2.0, 1.2)
        for k, u in enumerate((1.5, 2.5)):
            chair_at("chair%d" % k, u, 1.65, 180.0, 6.0 - 9.0 * k)
            chair_at("chair%d" % (k + 2), u, 3.75, 0.0, -5.0 + 11.0 * k)
        chair_at("chair4", 0.55, 2.7, 90.0, 8.0)
        chair_at("chair5", 3.45, 2.7, -90.0, -4.0)
        whiteboard(sc, name, "whiteboard",
                   against(f, "right", 1.8, 1.8, 0.02, 0.0), 1.8)
        bookshelf(sc, name, "shelf0",
                  against(f, "back", 0.4, SHELF_W, SHELF_D, 0.01), rng, LOW)
        lamps = ((1.5, 2.7), (2.5, 2.7))
    else:                                           # small library
        for k, w0 in enumerate((1.0, 1.95, 2.9)):
            bookshelf(sc, name, "shelf%d" % k,
                      against(f, "right", w0, SHELF_W, SHELF_D, 0.01), rng,
                      fill=0.7)
        bookshelf(sc, name, "shelf3",
                  against(f, "left", 2.7, SHELF_W, SHELF_D, 0.01), rng, LOW)
        desk(sc, name, "desk0", f.sub(1.2, 2.4), rng, monitor=False)
        chair_at("chair0", 2.0, 1.95, 180.0, 7.0)
        cabinet(sc, name, "cabinet0", against(f, "back", 1.5, 0.45, 0.6,
                                              0.02))
        lamps = ((1.4, 2.8), (2.6, 2.8))
    for k, (u, w) in enumerate(lamps):
        x, _, z = f((u, 0.0, w))
        lamp(sc, "%s_lamp%d" % (name, k), x, z)


# --- self-check --------------------------------------------------------------
def plane_basis(n):
    helper = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
    e1 = cross(n, helper)
    l1 = math.sqrt(dot(e1, e1))
    e1 = tuple(c / l1 for c in e1)
    return e1, cross(n, e1)


def overlap_2d(p, q, tol=1e-6):
    """Whether two convex polygons share more than an edge (separating
    axis test)."""
    for poly in (p, q):
        for k in range(len(poly)):
            a, b = poly[k], poly[(k + 1) % len(poly)]
            ax = (b[1] - a[1], a[0] - b[0])
            l = math.hypot(*ax)
            if l == 0:
                continue
            ax = (ax[0] / l, ax[1] / l)
            pp = [ax[0] * v[0] + ax[1] * v[1] for v in p]
            qq = [ax[0] * v[0] + ax[1] * v[1] for v in q]
            if min(max(pp), max(qq)) - max(min(pp), min(qq)) <= tol:
                return False
    return True


def inside_2d(points, poly, tol=1e-6):
    """Whether all points lie in the convex polygon (either winding)."""
    sign = 0
    for v in points:
        for k in range(len(poly)):
            a, b = poly[k], poly[(k + 1) % len(poly)]
            c = (b[0] - a[0]) * (v[1] - a[1]) - (b[1] - a[1]) * (v[0] - a[0])
            l = math.hypot(b[0] - a[0], b[1] - a[1])
            if abs(c / l) <= tol:
                continue
            s = 1 if c > 0 else -1
            if sign == 0:
                sign = s
            elif s != sign:
                return False
    return True


def unit_normal(v):
    n = quad_normal(v)
    l = math.sqrt(dot(n, n))
    return tuple(c / l for c in n)


class QuadIndex:
    """The quads hashed into a grid of 0.5 m cells by their bounding boxes."""

    CELL = 0.5

    def __init__(self, quads):
        self.quads = quads
        self.info = [(unit_normal(v), None) for v in quads]
        self.info = [(n, dot(n, v[0])) for (n, _), v in zip(self.info, quads)]
        self.cells = {}
        for idx, v in enumerate(quads):
            for key in self.keys(v):
                self.cells.setdefault(key, []).append(idx)

    def keys(self, v):
        lo = [int(math.floor((min(p[k] for p in v) - 1e-4) / self.CELL))
              for k in range(3)]
        hi = [int(math.floor((max(p[k] for p in v) + 1e-4) / self.CELL))
              for k in range(3)]
        return [(x, y, z) for x in range(lo[0], hi[0] + 1)
                for y in range(lo[1], hi[1] + 1)
                for z in range(lo[2], hi[2] + 1)]


def in_plane(n, d, v, tol=1e-4):
    return all(abs(dot(n, p) - d) < tol for p in v)


def project(n, v):
    e1, e2 = plane_basis(n)
    return [(dot(p, e1), dot(p, e2)) for p in v]


def check(sc, room_list):
    errors = []
    # planarity, size, winding
    for name, mat, v in sc.objects:
        n = quad_normal(v)
        ln = math.sqrt(dot(n, n))
        diag = max(math.sqrt(dot(sub(v[2], v[0]), sub(v[2], v[0]))),
                   math.sqrt(dot(sub(v[3], v[1]), sub(v[3], v[1]))))
        if ln < 1e-8:
            errors.append(name + ": degenerate")
            continue
        off = abs(dot(sub(v[3], v[0]), n)) / ln
        if off > 1e-3 * diag:
            errors.append(name + ": not planar (%g)" % off)
        n2 = cross(sub(v[2], v[0]), sub(v[3], v[0]))
        if dot(n, n2) <= 0:
            errors.append(name + ": not convex / mixed winding")
    # coplanar overlapping faces (facing either way)
    quads = [v for _, _, v in sc.objects]
    index = QuadIndex(quads)
    seen = set()
    for key in sorted(index.cells):
        members = index.cells[key]
        for x, ia in enumerate(members):
            na, da = index.info[ia]
            for ib in members[x + 1:]:
                nb, db = index.info[ib]
                if abs(dot(na, nb)) < 0.99999 or (ia, ib) in seen:
                    continue
                seen.add((ia, ib))
                if in_plane(na, da, quads[ib]) and overlap_2d(
                        project(na, quads[ia]), project(na, quads[ib])):
                    errors.append("%s and %s: coplanar and overlapping" %
                                  (sc.objects[ia][0], sc.objects[ib][0]))
    # every left-out face lies flat against a face that faces it
    for name, v, facing in sc.omitted:
        n = unit_normal(v)
        if dot(n, facing) < 0:
            n = tuple(-c for c in n)
        d = dot(n, v[0])
        c = mean(v)
        key = tuple(int(math.floor(c[k] / QuadIndex.CELL)) for k in range(3))
        ok = False
        for iq in index.cells.get(key, []):
            nq, dq = index.info[iq]
            if dot(nq, n) < -0.99999 and in_plane(n, d, quads[iq]) and \
                    inside_2d(project(n, v), project(n, quads[iq]), 1e-5):
                ok = True
                break
        if not ok:
            errors.append(name + ": left out but not covered")
    # furniture: no two boxes sunk into each other, all inside the room
    by_room = {}
    for b in sc.boxes:
        by_room.setdefault(b[0], []).append(b)
    rooms_by_name = {r["name"]: r for r in room_list}
    for rname, boxes in sorted(by_room.items()):
        r = rooms_by_name[rname]
        for b in boxes:
            lo, hi = b[5]
            if any(lo[k] < r["lo"][k] - 1e-9 or hi[k] > r["hi"][k] + 1e-9
                   for k in range(3)):
                errors.append(b[1] + ": box outside its room")
        for i, a in enumerate(boxes):
            for b in boxes[i + 1:]:
                if a[1] == b[1] and not a[2].aligned:
                    if a[2].key != b[2].key:
                        continue
                    la, ha, lb, hb = a[3], a[4], b[3], b[4]
                else:
                    (la, ha), (lb, hb) = a[5], b[5]
                if all(min(ha[k], hb[k]) - max(la[k], lb[k]) > 1e-6
                       for k in range(3)):
                    errors.append("%s / %s: boxes overlap" % (a[1], b[1]))
    for rname, iname, on_floor in sc.items:
        ys = [b[5][0][1] for b in sc.boxes if b[1] == iname]
        if on_floor and abs(min(ys)) > 1e-9:
            errors.append(iname + ": does not stand on the floor")
        if min(ys) < -1e-9:
            errors.append(iname + ": sunk into the floor")
    return errors


# --- output ------------------------------------------------------------------
def build(one_sided):
    sc = Scene(one_sided)
    room_list = rooms()
    walls, lamps = corridor(room_list)
    solid_faces(sc, shell_boxes() + walls, room_list)
    for k, (x, z) in enumerate(lamps):
        lamp(sc, "corridor_lamp%d" % k, x, z)
    rng = Rng(20240531)
    for r in room_list:
        room(sc, r, rng)
    return sc, room_list


def write(sc, path, one_sided):
    n = len(sc.objects)
    n_rooms = 2 * ROOMS_PER_SIDE
    about = (
        "One storey of an office building, %d quads, generated by "
        "scenes/make_building.py (edit that script, not this file). "
        "A %.1f m corridor, %.1f m wide and %.1f m high, closed at x = 0 and "
        "open at x = %.1f (no end wall: light escapes there), with %d offices "
        "of %.0f x %.0f m on its two sides, each behind a %.1f x %.1f m door "
        "opening with the leaf ajar: two-person offices, meeting rooms and "
        "small libraries with desks, chairs, filing cabinets, tables, "
        "whiteboards and bookshelves holding books and binders. Lamps: 0.6 x 0.6 m emissive quads "
        "1 cm below the ceiling, two per office and one every %.1f m in the "
        "corridor. " % (n, LENGTH - WALL, 2 * CORR_HALF, HEIGHT, LENGTH,
                        n_rooms, ROOM_W, ROOM_D, DOOR_W, DOOR_H,
                        CORRIDOR_LAMP_STEP))
    if one_sided:
        about += ("One-sided variant: only the inside surfaces; every wall is "
                  "one quad (split around its door) facing the room it "
                  "bounds, a wall between two rooms being one quad per room "
                  "0.1 m apart; door openings have reveal quads; no outside "
                  "faces. Same furniture as building.json.")
    else:
        about += ("Two-sided variant: walls (0.1 m thick), floor and ceiling "
                  "slabs are solid boxes and the scene is the boundary of "
                  "their union, so both sides of every wall are front faces; "
                  "doors are openings through the thick walls with reveal "
                  "faces. See building-one-sided.json for the one-sided "
                  "variant.")
    about += (" Furniture boxes face outward; a face resting flat against "
              "another surface (a bottom on the floor, a leg's top under a "
              "desk top, a book on a board) is left out.")
    lines = ["{",
             '"_about": %s,' % json.dumps(about),
             '"unit_scale": 1,',
             '"materials": {']
    mats = sorted(MATERIALS)
    for k, m in enumerate(mats):
        lines.append("  %s: %s%s" % (json.dumps(m),
                                     json.dumps(MATERIALS[m],
                                                separators=(", ", ": ")),
                     "," if k + 1 < len(mats) else ""))
    lines.append("},")
    lines.append('"objects": [')
    for k, (name, mat, v) in enumerate(sc.objects):
        obj = {"name": name, "type": "quad", "material": mat,
               "vertices": [list(p) for p in v]}
        lines.append(json.dumps(obj, separators=(",", ":")) +
                     ("," if k + 1 < n else ""))
    lines.append("],")
    camera = {"position": [0.8, 1.6, -0.2],
              "look_at": [LENGTH, 1.3, 0.0],
              "up": [0, 1, 0], "fov_y_deg": 50, "resolution": [640, 360]}
    lines.append('"camera": %s' % json.dumps(camera))
    lines.append("}")
    text = "\n".join(lines) + "\n"
    with open(path, "w") as out:
        out.write(text)
    return n, len(text)


def main():
    status = 0
    for one_sided, fname in ((False, "building.json"),
                             (True, "building-one-sided.json")):
        sc, room_list = build(one_sided)
        errors = check(sc, room_list)
        if errors:
            for e in errors[:50]:
                print("error: " + e, file=sys.stderr)
            print("%s: %d errors, not written" % (fname, len(errors)),
                  file=sys.stderr)
            status = 1
            continue
        path = os.path.join(HERE, fname)
        n, size = write(sc, path, one_sided)
        print("%s: %d quads, %d bytes" % (os.path.relpath(path), n, size))
    return status


if __name__ == "__main__":
    sys.exit(main())

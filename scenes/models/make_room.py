"""Writes room.obj and room.mtl beside this script: a furnished living room of about 10^4
triangles for `wavrad import` (standard library only; deterministic, so the committed files are
what it writes):

    python3 scenes/models/make_room.py

The room is 5 m (x) by 4 m (z) by 2.7 m (y up), in metres. Walls, floor and ceiling are fine
grids (the light varies over them); every surface faces into the room or out of its solid
(counter-clockwise seen from the front, as OBJ has it). Furniture: a table with four chairs,
a bookcase of shelves and books, a sofa, a rug, a floor lamp whose shade glows (MTL Ke) and a
window in the west wall whose pane lets in daylight (Ke). One object per piece, one material
per part of it, so that the import makes one surface of each: a few dozen surfaces.
"""

import math
import os
import random

HERE = os.path.dirname(os.path.abspath(__file__))
W, D, H = 5.0, 4.0, 2.7  # room: x, z, y

MATERIALS = {
    # name: (Kd, Ke or None)
    "oak-floor": ((0.55, 0.38, 0.22), None),
    "ceiling-white": ((0.85, 0.85, 0.83), None),
    "wall-paint": ((0.78, 0.74, 0.66), None),
    "accent-paint": ((0.35, 0.48, 0.55), None),
    "window-white": ((0.88, 0.88, 0.88), None),
    "daylight": ((0.0, 0.0, 0.0), (6.0, 7.0, 8.5)),
    "walnut": ((0.32, 0.2, 0.12), None),
    "beech": ((0.7, 0.52, 0.33), None),
    "fabric-blue": ((0.15, 0.22, 0.45), None),
    "fabric-grey": ((0.45, 0.45, 0.47), None),
    "rug-red": ((0.55, 0.12, 0.1), None),
    "book-red": ((0.6, 0.1, 0.08), None),
    "book-green": ((0.12, 0.4, 0.18), None),
    "book-cream": ((0.85, 0.8, 0.65), None),
    "book-navy": ((0.08, 0.1, 0.3), None),
    "brass": ((0.65, 0.5, 0.22), None),
    "lampshade": ((0.0, 0.0, 0.0), (40.0, 32.0, 20.0)),
}


class Obj:
    def __init__(self):
        self.vertices = []
        self.groups = []  # (object, material, [triangles])
        self.current = None

    def start(self, obj, material):
        self.current = (obj, material, [])
        self.groups.append(self.current)

    def vertex(self, p):
        self.vertices.append(tuple(p))
        return len(self.vertices)  # 1-based

    def tri(self, a, b, c):
        self.current[2].append((a, b, c))

    def quad(self, a, b, c, d):
        self.tri(a, b, c)
        self.tri(a, c, d)


def add(p, q):
    return [p[i] + q[i] for i in range(3)]


def scale(p, s):
    return [x * s for x in p]


def grid(o, origin, u, v, nu, nv, hole=None):
    """A parallelogram origin + s u + t v split into nu x nv quads; front = u x v.
    `hole(s, t)` leaves out the cells whose centre it is true for."""
    index = {}
    for i in range(nu + 1):
        for j in range(nv + 1):
            index[i, j] = None
    for i in range(nu):
        for j in range(nv):
            s, t = (i + 0.5) / nu, (j + 0.5) / nv
            if hole and hole(s, t):
                continue
            corners = []
            for (a, b) in ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)):
                if index[a, b] is None:
                    index[a, b] = o.vertex(add(origin, add(scale(u, a / nu), scale(v, b / nv))))
                corners.append(index[a, b])
            o.quad(*corners)


def box(o, lo, hi, bottom=False, n=1):
    """An axis-aligned box, faces outwards; the bottom only when asked (boxes stand on things)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    grid(o, [x0, y1, z0], [0, 0, dz], [dx, 0, 0], n, n)  # top (+y)
    grid(o, [x0, y0, z0], [0, dy, 0], [dx, 0, 0], n, n)  # front (-z)
    grid(o, [x1, y0, z1], [0, dy, 0], [-dx, 0, 0], n, n)  # back (+z)
    grid(o, [x0, y0, z1], [0, dy, 0], [0, 0, -dz], n, n)  # -x
    grid(o, [x1, y0, z0], [0, dy, 0], [0, 0, dz], n, n)  # +x
    if bottom:
        grid(o, [x0, y0, z0], [dx, 0, 0], [0, 0, dz], n, n)


def frustum(o, centre, r0, r1, height, segments, top=True, rings=1):
    """A cylinder or truncated cone around +y from `centre`, outwards, with its top cap."""
    cx, cy, cz = centre
    rows = []
    for k in range(rings + 1):
        f = k / rings
        r, y = r0 + (r1 - r0) * f, cy + height * f
        rows.append(
            [o.vertex([cx + r * math.cos(2 * math.pi * i / segments), y, cz + r * math.sin(2 * math.pi * i / segments)]) for i in range(segments)]
        )
    for k in range(rings):
        a, b = rows[k], rows[k + 1]
        for i in range(segments):
            j = (i + 1) % segments
            # counter-clockwise seen from outside: the angle grows towards +z from +x
            o.quad(a[i], b[i], b[j], a[j])
    if top:
        c = o.vertex([cx, cy + height, cz])
        ring = rows[-1]
        for i in range(segments):
            o.tri(c, ring[(i + 1) % segments], ring[i])


def room(o):
    window = (0.3, 0.7, 0.3, 0.85)  # west wall (x = 0): s along z, t along y
    o.start("floor", "oak-floor")
    grid(o, [0, 0, 0], [0, 0, D], [W, 0, 0], 24, 30)
    o.start("ceiling", "ceiling-white")
    grid(o, [0, H, 0], [W, 0, 0], [0, 0, D], 25, 20)
    o.start("wall-south", "wall-paint")  # z = 0, facing +z
    grid(o, [0, 0, 0], [W, 0, 0], [0, H, 0], 25, 12)
    o.start("wall-north", "accent-paint")  # z = D, facing -z
    grid(o, [W, 0, D], [-W, 0, 0], [0, H, 0], 25, 12)
    o.start("wall-east", "wall-paint")  # x = W, facing -x
    grid(o, [W, 0, 0], [0, 0, D], [0, H, 0], 20, 12)
    o.start("wall-west", "wall-paint")  # x = 0, facing +x, with the window's opening
    s0, s1, t0, t1 = window
    grid(o, [0, 0, D], [0, 0, -D], [0, H, 0], 20, 20, hole=lambda s, t: s0 < s < s1 and t0 < t < t1)
    # the pane fills the opening, facing in; the frame around it and its bars stand on it
    z0, z1, y0, y1 = D * (1 - s1), D * (1 - s0), H * t0, H * t1
    o.start("window", "daylight")
    grid(o, [0.0, y0, z1], [0, 0, z0 - z1], [0, y1 - y0, 0], 8, 8)
    o.start("window-frame", "window-white")
    f = 0.05
    box(o, [0.0, y0 - f, z0 - f], [0.06, y0, z1 + f], bottom=True)
    box(o, [0.0, y1, z0 - f], [0.06, y1 + f, z1 + f], bottom=True)
    box(o, [0.0, y0, z0 - f], [0.06, y1, z0], bottom=True)
    box(o, [0.0, y0, z1], [0.06, y1, z1 + f], bottom=True)
    zm, ym = (z0 + z1) / 2, (y0 + y1) / 2
    box(o, [0.0, y0, zm - 0.02], [0.04, y1, zm + 0.02], bottom=True)
    box(o, [0.0, ym - 0.02, z0], [0.04, ym + 0.02, zm - 0.02], bottom=True)
    box(o, [0.0, ym - 0.02, zm + 0.02], [0.04, ym + 0.02, z1], bottom=True)


def table(o, cx, cz):
    o.start("table", "walnut")
    top = 0.74
    box(o, [cx - 0.8, top - 0.04, cz - 0.45], [cx + 0.8, top, cz + 0.45], bottom=True, n=6)
    for sx in (-1, 1):
        for sz in (-1, 1):
            frustum(o, [cx + sx * 0.7, 0, cz + sz * 0.36], 0.035, 0.03, top - 0.04, 16, top=False, rings=3)


def chair(o, name, cx, cz, facing):
    """A chair whose sitter looks along `facing` (+1: +z, -1: -z)."""
    seat = 0.45
    o.start(name, "beech")
    for sx in (-1, 1):
        for sz in (-1, 1):
            frustum(o, [cx + sx * 0.18, 0, cz + sz * 0.18], 0.02, 0.018, seat - 0.04, 12, top=False, rings=2)
    back = cz - facing * 0.2
    for sx in (-1, 1):
        box(o, [cx + sx * 0.18 - 0.02, seat, back - 0.02], [cx + sx * 0.18 + 0.02, seat + 0.45, back + 0.02])
    box(o, [cx - 0.2, seat + 0.3, back - 0.015], [cx + 0.2, seat + 0.45, back + 0.015], n=3)
    o.start(name, "fabric-blue")
    box(o, [cx - 0.22, seat - 0.04, cz - 0.22], [cx + 0.22, seat + 0.03, cz + 0.22], bottom=True, n=4)


def bookcase(o, rng):
    """Against the east wall (x = W): a frame of boards and four rows of books."""
    x0, x1, z0, z1, top = W - 0.35, W - 0.01, 1.2, 2.8, 2.0
    o.start("bookcase", "walnut")
    t = 0.025
    box(o, [x0, 0, z0], [x1, top, z0 + t], n=2)
    box(o, [x0, 0, z1 - t], [x1, top, z1], n=2)
    box(o, [x1 - t, 0, z0 + t], [x1, top, z1 - t], n=2)
    shelves = [0.0, 0.45, 0.9, 1.35, 1.8]
    for y in shelves:
        box(o, [x0, y, z0 + t], [x1 - t, y + t, z1 - t], n=2)
    box(o, [x0, top - t, z0 + t], [x1 - t, top, z1 - t])
    colours = ["book-red", "book-green", "book-cream", "book-navy"]
    books = {c: [] for c in colours}
    for y in shelves[:4]:
        z = z0 + t + 0.01
        while True:
            w = rng.uniform(0.02, 0.05)
            h = rng.uniform(0.2, 0.36)
            d = rng.uniform(0.18, 0.26)
            if z + w > z1 - t - 0.01:
                break
            books[rng.choice(colours)].append(([x1 - t - d, y + t, z], [x1 - t - 0.005, y + t + h, z + w]))
            z += w + rng.uniform(0.0, 0.006)
    for c in colours:
        o.start("books", c)
        for lo, hi in books[c]:
            box(o, lo, hi)


def sofa(o):
    """Against the north wall, facing the room (-z)."""
    x0, x1, z0, z1 = 1.6, 3.6, D - 0.95, D - 0.05
    o.start("sofa", "fabric-grey")
    box(o, [x0 + 0.15, 0.08, z0], [x1 - 0.15, 0.42, z1 - 0.2], n=6)  # seat
    box(o, [x0 + 0.15, 0.08, z1 - 0.2], [x1 - 0.15, 0.85, z1], n=6)  # back
    box(o, [x0, 0.08, z0], [x0 + 0.15, 0.62, z1], n=3)  # arms
    box(o, [x1 - 0.15, 0.08, z0], [x1, 0.62, z1], n=3)
    for k in range(3):  # cushions
        a = x0 + 0.15 + k * (x1 - x0 - 0.3) / 3
        box(o, [a + 0.01, 0.42, z0 + 0.02], [a + (x1 - x0 - 0.3) / 3 - 0.01, 0.52, z1 - 0.22], n=3)
    o.start("sofa", "walnut")
    for x in (x0 + 0.05, x1 - 0.05):
        for z in (z0 + 0.05, z1 - 0.05):
            frustum(o, [x, 0, z], 0.025, 0.02, 0.08, 10, top=False)


def lamp(o):
    """A floor lamp in the south-east corner; its shade glows."""
    cx, cz = W - 0.45, 0.45
    o.start("lamp", "brass")
    frustum(o, [cx, 0, cz], 0.16, 0.15, 0.02, 32)
    frustum(o, [cx, 0.02, cz], 0.012, 0.012, 1.4, 12, top=False, rings=6)
    o.start("lamp-shade", "lampshade")
    frustum(o, [cx, 1.38, cz], 0.22, 0.13, 0.28, 48, top=True, rings=4)


def main():
    rng = random.Random(7)
    o = Obj()
    room(o)
    o.start("rug", "rug-red")
    grid(o, [1.3, 0.005, 0.9], [0, 0, 2.0], [2.6, 0, 0], 10, 13)
    table(o, 2.4, 1.9)
    chair(o, "chair-1", 1.9, 1.25, +1)
    chair(o, "chair-2", 2.9, 1.25, +1)
    chair(o, "chair-3", 1.9, 2.55, -1)
    chair(o, "chair-4", 2.9, 2.55, -1)
    bookcase(o, rng)
    sofa(o)
    lamp(o)
    with open(os.path.join(HERE, "room.mtl"), "w") as f:
        f.write("# materials of room.obj (written by make_room.py)\n")
        for name, (kd, ke) in MATERIALS.items():
            f.write(f"\nnewmtl {name}\nKd {kd[0]} {kd[1]} {kd[2]}\n")
            if ke:
                f.write(f"Ke {ke[0]} {ke[1]} {ke[2]}\n")
    triangles = 0
    with open(os.path.join(HERE, "room.obj"), "w") as f:
        f.write("# A furnished room (written by make_room.py): metres, y up\nmtllib room.mtl\n")
        for p in o.vertices:
            f.write("v {:.4f} {:.4f} {:.4f}\n".format(*p))
        for obj, material, tris in o.groups:
            f.write(f"o {obj}\nusemtl {material}\n")
            for t in tris:
                f.write("f {} {} {}\n".format(*t))
            triangles += len(tris)
    surfaces = len({(obj, m) for obj, m, _ in o.groups})
    print(f"room.obj: {len(o.vertices)} vertices, {triangles} triangles, {surfaces} surfaces")


if __name__ == "__main__":
    main()

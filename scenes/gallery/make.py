#!/usr/bin/env python3
"""Writes the gallery of 3D test scenes (rooms with boxes, rotated boxes, a small object, a box
against a wall, a light in a corner, spheres and boxes as meshes, small objects placed
otherwise, two boxes a narrow gap apart, everyday shapes) as job documents at the solver's
defaults (hierarchical, order 1, the default epsilon and element size). The tests in
tests/gallery.rs solve each (of furniture(), the first six) and compare it with a
path-traced reference.

    python3 scenes/gallery/make.py        # rewrites scenes/gallery/*.json
"""
import json
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
WHITE, RED, GREEN = 0.7, [0.63, 0.07, 0.06], [0.14, 0.45, 0.09]


def quad(name, p0, p1, p3, rho, emission=None):
    """The parallelogram p0, p1, p0 + (p1 - p0) + (p3 - p0), p3, front by the right hand."""
    p2 = [p1[i] + p3[i] - p0[i] for i in range(3)]
    s = {"name": name, "corners": [r(p0), r(p1), r(p2), r(p3)], "reflectance": rho}
    if emission is not None:
        s["emission"] = emission
    return s


def r(p):
    return [round(x, 9) + 0.0 for x in p]


def room(w, h, d, left=WHITE, right=WHITE):
    """The inside of the box [0,w] x [0,h] x [0,d], every face toward the inside; y is up."""
    return [
        quad("floor", [0, 0, 0], [0, 0, d], [w, 0, 0], WHITE),
        quad("ceiling", [0, h, 0], [w, h, 0], [0, h, d], WHITE),
        quad("back", [0, 0, d], [0, h, d], [w, 0, d], WHITE),
        quad("front", [0, 0, 0], [w, 0, 0], [0, h, 0], WHITE),
        quad("left", [0, 0, 0], [0, h, 0], [0, 0, d], left),
        quad("right", [w, 0, 0], [w, 0, d], [w, h, 0], right),
    ]


def ceiling_light(x0, z0, x1, z1, y, e):
    """A light hanging at height y, facing down."""
    return quad("light", [x0, y, z0], [x1, y, z0], [x0, y, z1], 0.0, e)


def box(name, cx, cz, sx, sy, sz, angle_deg=0.0, rho=WHITE, y0=0.0):
    """An open-bottomed box standing at (cx, y0, cz), sides sx x sz, height sy, turned by
    angle_deg about the vertical: four sides and a top, facing out."""
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)

    def at(u, v, y):  # local (u along x, v along z) to world
        return [cx + c * u - s * v, y0 + y, cz + s * u + c * v]

    hx, hz = sx / 2, sz / 2
    return [
        quad(f"{name}-top", at(-hx, -hz, sy), at(-hx, hz, sy), at(hx, -hz, sy), rho),
        # -z side, normal -z: p1 - p0 along +x, p3 - p0 along +y gives (x × y) = +z: swap
        quad(f"{name}-south", at(-hx, -hz, 0), at(-hx, -hz, sy), at(hx, -hz, 0), rho),
        quad(f"{name}-north", at(-hx, hz, 0), at(hx, hz, 0), at(-hx, hz, sy), rho),
        quad(f"{name}-west", at(-hx, -hz, 0), at(-hx, hz, 0), at(-hx, -hz, sy), rho),
        quad(f"{name}-east", at(hx, -hz, 0), at(hx, -hz, sy), at(hx, hz, 0), rho),
    ]


def box_mesh(name, cx, cz, sx, sy, sz, angle_deg=0.0, rho=WHITE):
    """The box of box() as one mesh surface: its top and four sides, two triangles each."""
    positions, triangles = [], []
    for q in box(name, cx, cz, sx, sy, sz, angle_deg, rho):
        base = len(positions)
        positions += q["corners"]
        triangles += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return {"name": name, "mesh": {"positions": positions, "triangles": triangles},
            "reflectance": rho}


def icosphere(name, centre, radius, level, rho=WHITE):
    """A sphere as a mesh facing out: the icosahedron split `level` times into four,
    20 * 4^level triangles."""
    t = (1 + 5 ** 0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    v = [[x / math.sqrt(sum(c * c for c in p)) for x in p] for p in v]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(level):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = [(v[a][i] + v[b][i]) / 2 for i in range(3)]
                n = math.sqrt(sum(c * c for c in p))
                v.append([c / n for c in p])
                mid[key] = len(v) - 1
            return mid[key]

        f = [g for a, b, c in f
             for g in ([a, m(a, b), m(c, a)], [b, m(b, c), m(a, b)], [c, m(c, a), m(b, c)],
                       [m(a, b), m(b, c), m(c, a)])]
    positions = [r([centre[i] + radius * p[i] for i in range(3)]) for p in v]
    return {"name": name, "mesh": {"positions": positions, "triangles": f}, "reflectance": rho}


def doc(name, surfaces, eye=None, look=None, grid=4):
    """A job document; without an eye, the picture's camera is framed automatically (in a
    closed room, from an upper corner inside it)."""
    output = {"grid": grid}
    if eye is not None:
        output["camera"] = {"eye": eye, "look_at": look, "up": [0, 1, 0], "fov_deg": 60}
    return {
        "scene": {"kind": "3d", "name": name, "surfaces": surfaces},
        "solver": {"method": "hierarchical"},
        "output": output,
    }


def grid_room(n, meshes=False):
    """A 10 x 10 x 10 room with an n x n grid of boxes and a 2 x 2 light under the ceiling;
    each box one mesh of ten triangles when `meshes`."""
    surfaces = room(10, 10, 10)
    surfaces.append(ceiling_light(4, 4, 6, 6, 9.99, 10.0))
    step = 10 / (n + 1)
    size = 0.5 * step
    for i in range(n):
        for j in range(n):
            height = size * (1.0 + 0.5 * ((i + 2 * j) % 3))
            at = (f"box{i}{j}", step * (i + 1), step * (j + 1), size, height, size)
            if meshes:
                surfaces.append(box_mesh(*at))
            else:
                surfaces += box(*at)
    kind = " as meshes" if meshes else ""
    return doc(f"A room with {n} x {n} boxes{kind}", surfaces)


def rotated_boxes():
    surfaces = room(10, 6, 10, left=RED, right=GREEN)
    surfaces.append(ceiling_light(4, 4, 6, 6, 5.99, 12.0))
    surfaces += box("a", 3, 3, 2, 2, 2, 30)
    surfaces += box("b", 7, 4, 1.5, 3, 1.5, 45)
    surfaces += box("c", 4.5, 7.5, 3, 1, 1.5, -20)
    return doc("Rotated boxes", surfaces)


def small_object():
    surfaces = room(10, 10, 10)
    surfaces.append(ceiling_light(4, 4, 6, 6, 9.99, 10.0))
    surfaces += box("cube", 5, 5, 0.3, 0.3, 0.3, 0, [0.8, 0.3, 0.2])
    return doc("A small cube in a large room", surfaces, [5, 1, 3], [5, 0.15, 5])


def small_objects():
    """Small objects placed otherwise than the gallery's small cube, the scenes of the
    "Small objects elsewhere in the room" section of benches/README.md, and two boxes a
    narrow gap apart. Each is tested at the defaults in tests/gallery.rs."""
    cube = [0.8, 0.3, 0.2]

    def tall_room():
        s = room(10, 10, 10)
        s.append(ceiling_light(4, 4, 6, 6, 9.99, 10.0))
        return s

    in_a_corner = tall_room() + box("cube", 1.5, 1.5, 0.3, 0.3, 0.3, 0, cube)
    turned = tall_room() + box("cube", 5, 5, 0.3, 0.3, 0.3, 30, cube)
    slab = tall_room() + box("slab", 3, 6, 0.6, 0.15, 0.6, 0, cube)
    corner_light = room(8, 4, 6, left=RED, right=GREEN)
    corner_light.append(ceiling_light(0.3, 0.3, 1.8, 1.8, 3.9, 20.0))
    corner_light += box("cube", 5, 3.5, 0.25, 0.25, 0.25, 15, cube)
    beside = room(10, 6, 10, left=RED, right=GREEN)
    beside.append(ceiling_light(4, 4, 6, 6, 5.99, 12.0))
    beside += box("a", 3, 3, 2, 2, 2, 30)
    beside += box("cube", 6, 2, 0.3, 0.3, 0.3, 0, [0.8, 0.8, 0.8])
    # two boxes side by side, 2 cm apart: each sees the other's side across the gap
    apart = room(10, 6, 10, left=RED, right=GREEN)
    apart.append(ceiling_light(4, 4, 6, 6, 5.99, 12.0))
    apart += box("a", 4.75, 5, 0.5, 0.5, 0.5, 0, [0.8, 0.8, 0.8])
    apart += box("b", 5.27, 5, 0.5, 0.8, 0.5, 0, [0.2, 0.4, 0.8])
    return {
        "two-boxes-apart": doc("Two boxes 2 cm apart", apart),
        "small-cube-in-a-corner": doc("A small cube near a corner", in_a_corner),
        "small-cube-turned": doc("A small cube turned by 30 degrees", turned),
        "small-slab": doc("A flat slab in a large room", slab),
        "small-cube-corner-light": doc("A small turned cube in a room lit from a corner", corner_light),
        "small-cube-beside-a-box": doc("A small cube beside a large box", beside),
    }


def box_against_wall():
    surfaces = room(8, 5, 8)
    surfaces.append(ceiling_light(3, 3, 5, 5, 4.99, 10.0))
    # the box's north side lies in the back wall's plane: left out, the wall is there
    b = box("box", 4, 7, 3, 2, 2, 0, [0.3, 0.5, 0.8])
    surfaces += [s for s in b if not s["name"].endswith("-north")]
    return doc("A box against a wall", surfaces)


def corner_light():
    surfaces = room(8, 4, 6, left=RED, right=GREEN)
    surfaces.append(ceiling_light(0.3, 0.3, 1.8, 1.8, 3.9, 20.0))
    surfaces += box("box", 5, 3.5, 2, 1.5, 2, 15)
    return doc("A light in a corner", surfaces)


def meshes_on_a_floor():
    """Two icospheres and two turned boxes, each one mesh, in a room of parallelograms."""
    surfaces = room(10, 6, 10, left=RED, right=GREEN)
    surfaces.append(ceiling_light(4, 4, 6, 6, 5.99, 12.0))
    surfaces.append(icosphere("ball", [3, 1.2, 4], 1.2, 2, [0.8, 0.6, 0.3]))
    surfaces.append(icosphere("small-ball", [6.5, 0.5, 3], 0.5, 1))
    surfaces.append(box_mesh("block", 6.5, 6.5, 2, 2.5, 1.5, 30, [0.3, 0.5, 0.7]))
    surfaces.append(box_mesh("slab", 3, 7.5, 2.5, 0.6, 1.5, -15))
    return doc("Meshes on a floor", surfaces)


def closed_box(name, cx, cz, sx, sy, sz, y0, rho=WHITE, angle_deg=0.0):
    """The box of box() with its bottom, facing down: a box that does not stand on the floor."""
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)

    def at(u, v):
        return [cx + c * u - s * v, y0, cz + s * u + c * v]

    hx, hz = sx / 2, sz / 2
    bottom = quad(f"{name}-bottom", at(-hx, -hz), at(hx, -hz), at(-hx, hz), rho)
    return box(name, cx, cz, sx, sy, sz, angle_deg, rho, y0) + [bottom]


def furniture():
    """Scenes of everyday shapes, written after the default element size followed the smallest
    face and the narrowest gap, to try it on scenes it was not made from (the shelf near a
    side wall came later, with the near occluders' rule; the cabinet and the turned box near
    a wall with the narrow gaps' sizes where they are). All but the box above the floor and
    the shelf meet the gallery's requirement at the defaults and are tested; those two do not
    yet (benches/README.md, "Scenes it was not made from")."""
    wood = [0.6, 0.4, 0.2]

    def tall_room():
        s = room(10, 10, 10)
        s.append(ceiling_light(4, 4, 6, 6, 9.99, 10.0))
        return s

    def low_room():
        s = room(10, 6, 10, left=RED, right=GREEN)
        s.append(ceiling_light(4, 4, 6, 6, 5.99, 12.0))
        return s

    def corner_lit():
        s = room(8, 4, 6, left=RED, right=GREEN)
        s.append(ceiling_light(0.3, 0.3, 1.8, 1.8, 3.9, 20.0))
        return s

    on_a_box = tall_room() + box("base", 5, 5, 2, 1, 2)
    on_a_box += box("cube", 5.3, 5.2, 0.3, 0.3, 0.3, 20, [0.8, 0.3, 0.2], 1.0)
    pillar = tall_room() + box("pillar", 3, 6, 0.2, 4, 0.2, 0, [0.3, 0.5, 0.8])
    partition = corner_lit() + box("partition", 4, 3, 0.05, 3, 4, 0, [0.7, 0.7, 0.7])
    table = corner_lit() + closed_box("top", 5, 3, 2, 0.05, 1, 0.75, wood)
    for i, (x, z) in enumerate([(4.1, 2.6), (5.9, 2.6), (4.1, 3.4), (5.9, 3.4)]):
        table += box(f"leg{i}", x, z, 0.06, 0.75, 0.06, 0, wood)
    near_wall = room(10, 5, 10)
    near_wall.append(ceiling_light(0.1, 4, 1.1, 6, 4.99, 15.0))
    near_wall += box("b", 5, 5, 2, 1.5, 2, 20, [0.3, 0.5, 0.8])
    stack = tall_room() + box("c1", 5, 5, 1, 1, 1)
    stack += box("c2", 5, 5, 0.7, 0.7, 0.7, 25, [0.8, 0.3, 0.2], 1.0)
    stack += box("c3", 5, 5, 0.4, 0.4, 0.4, 50, [0.2, 0.6, 0.3], 1.7)
    lifted = low_room() + closed_box("lifted", 3, 4, 1, 1, 1, 0.02, [0.3, 0.5, 0.8])
    shelf = low_room() + closed_box("shelf", 5, 9.7, 1.5, 0.04, 0.4, 2.0, [0.8, 0.8, 0.8])
    side_shelf = corner_lit() + closed_box("shelf", 7.7, 3, 0.4, 0.04, 1.5, 1.5, [0.8, 0.8, 0.8])
    # a cabinet whose back is 1 cm from the back wall, and a box turned by 5 degrees whose
    # nearest edge is 5 mm from the right wall: gaps below a 256th of the diagonal
    cabinet = corner_lit() + box("cab", 4, 5.74, 1.2, 2.0, 0.5, 0, wood)
    reach = 0.5 * (math.cos(math.radians(5)) + math.sin(math.radians(5)))
    turned_near_wall = corner_lit() + box("w", 8 - 0.005 - reach, 3, 1, 1, 1, 5, [0.8, 0.8, 0.3])
    return {
        "cube-on-a-box": doc("A small cube on a box", on_a_box),
        "pillar": doc("A thin pillar", pillar),
        "partition": doc("A thin partition in a room lit from a corner", partition),
        "table": doc("A table on thin legs", table),
        "light-near-a-wall": doc("A light 10 cm from a wall", near_wall),
        "stack": doc("Three cubes stacked, each turned", stack),
        "lifted-box": doc("A box 2 cm above the floor", lifted),
        "shelf": doc("A thin shelf 10 cm from a wall", shelf),
        "side-shelf": doc("A shelf 10 cm from a side wall, lit from a corner", side_shelf),
        "cabinet": doc("A cabinet 1 cm from the wall", cabinet),
        "turned-box-near-a-wall": doc("A turned box 5 mm from a wall", turned_near_wall),
    }


def main():
    scenes = {
        "room-3x3": grid_room(3),
        "room-7x7": grid_room(7),
        "room-3x3-meshes": grid_room(3, meshes=True),
        "rotated-boxes": rotated_boxes(),
        "small-object": small_object(),
        "box-against-wall": box_against_wall(),
        "corner-light": corner_light(),
        "meshes-on-a-floor": meshes_on_a_floor(),
        **small_objects(),
        **furniture(),
    }
    for name, d in scenes.items():
        with open(os.path.join(HERE, f"{name}.json"), "w") as f:
            json.dump(d, f, indent=1)
            f.write("\n")


if __name__ == "__main__":
    main()

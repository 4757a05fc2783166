#!/usr/bin/env python3
"""Writes the furnished room (tests/tests/bounce.rs): a closed room 4 × 2.6 × 3.2 m whose six
walls are two triangles each (white walls and ceiling, a wooden floor), two 0.6 m square panel
lights 1 mm under the ceiling (no declared reach), and furniture: a table on four legs, a
sofa, a bookshelf and a cabinet, all boxes of 24 vertices. The camera stands in a corner.

    python3 scripts/make_furnished_room.py OUT.gltf
"""
import json
import math
import sys

from gltf_buffer import Buffer, document, emitter, lambertian
from make_textured_materials import look_at
from make_two_triangle_floor import cuboid

W, H, D = 4.0, 2.6, 3.2


def inward_room(w, h, d):
    """The walls and ceiling of a room [−w/2, w/2] × [0, h] × [−d/2, d/2], facing in (the
    floor is its own mesh): 20 vertices."""
    pos, nrm, idx = cuboid([w / 2, h / 2, d / 2])
    # cuboid's faces come 4 vertices and 6 indices each, in the order −x, +x, −y, +y, −z, +z.
    keep = [f for f in range(6) if f != 2]
    pos = [[x, y + h / 2, z] for f in keep for x, y, z in pos[4 * f:4 * f + 4]]
    nrm = [[-c for c in n] for f in keep for n in nrm[4 * f:4 * f + 4]]
    faces = [idx[6 * f:6 * f + 6] for f in keep]
    idx = [i - 4 * f + 4 * k for k, (f, t) in enumerate(zip(keep, faces)) for j in range(0, 6, 3)
           for i in (t[j], t[j + 2], t[j + 1])]
    return pos, nrm, idx


def panel(h):
    """A square light of half-side h facing down (−y)."""
    return [[-h, 0, -h], [h, 0, -h], [h, 0, h], [-h, 0, h]], [[0, -1, 0]] * 4, [0, 1, 2, 0, 2, 3]


def main(out):
    white, wood = lambertian("white", [0.75, 0.75, 0.72]), lambertian("wood", [0.42, 0.28, 0.16])
    fabric, shelf = lambertian("fabric", [0.2, 0.3, 0.55]), lambertian("shelf", [0.6, 0.55, 0.45])
    light = emitter("panel", [12.0, 11.5, 10.5])
    objects = [("room", inward_room(W, H, D), white, [0, 0, 0]),
               ("floor", ([[-W / 2, 0, -D / 2], [-W / 2, 0, D / 2], [W / 2, 0, D / 2], [W / 2, 0, -D / 2]],
                          [[0, 1, 0]] * 4, [0, 1, 2, 0, 2, 3]), wood, [0, 0, 0])]
    # The table: a top on four legs.
    objects.append(("table_top", cuboid([0.6, 0.025, 0.4]), wood, [0.3, 0.75, -0.2]))
    for k, (x, z) in enumerate([(-0.25, -0.55), (-0.25, 0.15), (0.85, -0.55), (0.85, 0.15)]):
        objects.append((f"table_leg_{k}", cuboid([0.03, 0.36, 0.03]), wood, [x, 0.36, z]))
    objects += [
        ("sofa_seat", cuboid([0.9, 0.2, 0.4]), fabric, [0.2, 0.2, 1.05]),
        ("sofa_back", cuboid([0.9, 0.4, 0.1]), fabric, [0.2, 0.4, 1.5]),
        ("bookshelf", cuboid([0.5, 0.9, 0.18]), shelf, [-1.3, 0.9, -1.4]),
        ("cabinet", cuboid([0.3, 0.45, 0.25]), shelf, [1.65, 0.45, -1.3]),
        ("panel_a", panel(0.3), light, [-0.8, H - 0.001, -0.3]),
        ("panel_b", panel(0.3), light, [1.0, H - 0.001, 0.6]),
    ]
    eye = [-1.85, 1.6, 1.45]
    camera = (eye, look_at(eye, [0.4, 0.6, -0.4]))
    doc = document("kage scripts/make_furnished_room.py", Buffer(), objects, camera, math.radians(60), 4 / 3)
    with open(out, "w") as f:
        json.dump(doc, f)


if __name__ == "__main__":
    main(sys.argv[1])

#!/usr/bin/env python3
"""Writes the low-poly box scene (tests/tests/bounce.rs): a 1 m box of 24 vertices (flat
normals) resting on a two-triangle floor 8 m across, under a 1 m quad light 3 m up and 2 m to
+x, so the box's -x face is turned away from the light and sees only the floor's bounce. The
camera looks at that face. A hard case for the radiance cache: records must not be used across
the box's 90° edges.

    python3 scripts/make_lowpoly_box.py OUT.gltf
"""
import json
import math
import sys

from gltf_buffer import Buffer, document, emitter, lambertian
from make_textured_materials import look_at
from make_two_triangle_floor import cuboid


def quad(h, normal_y):
    """A square of half-side h in the y = 0 plane, facing +y or -y: two triangles."""
    corners = [[-h, 0, -h], [-h, 0, h], [h, 0, h], [h, 0, -h]]
    indices = [0, 1, 2, 0, 2, 3] if normal_y > 0 else [0, 2, 1, 0, 3, 2]
    return corners, [[0, normal_y, 0]] * 4, indices


def main(out):
    grey = lambertian("grey", [0.8, 0.8, 0.8])
    objects = [
        ("floor", quad(4.0, 1), grey, [0, 0, 0]),
        ("box", cuboid([0.5, 0.5, 0.5]), grey, [0, 0.5, 0]),
        ("light", quad(0.5, -1), emitter("light", [10, 10, 10]), [2.0, 3.0, 0.0]),
    ]
    eye = [-3.0, 1.5, 1.5]
    camera = (eye, look_at(eye, [-0.5, 0.5, 0.0]))
    doc = document("kage scripts/make_lowpoly_box.py", Buffer(), objects, camera, math.radians(40), 16 / 9)
    with open(out, "w") as f:
        json.dump(doc, f)


if __name__ == "__main__":
    main(sys.argv[1])

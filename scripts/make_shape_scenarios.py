#!/usr/bin/env python3
"""Writes the grasp scenarios whose target is not one flat face (config/scenarios/can_*.yaml,
bottle_*.yaml, box_*_turned.yaml) and their object definitions (config/objects/), from a few
numbers per world, with the placement rules of scripts/make_grasp_scenarios.py. Run from the
repository root: python3 scripts/make_shape_scenarios.py (plain Python 3, no packages). Geometry
conventions: config/scenarios/README.md; the definitions' forms: src/detector/object.h.

Rules (the same for every world, nothing tuned to one): the robot starts at the origin facing +x;
the target's centre (a cylinder's axis, a box's centre) is `distance_m` away at `bearing_deg`
(counter-clockwise from +x) and it stands upright on a 0.72 m table whose front edge is
perpendicular to the grasp's approach, 13 cm in front of that centre (the grasp frame's depth in the
photo worlds and can_table), or 2 cm in front of the target's nearest point if that is further.
- Cylinders (cans, bottles): a photograph as the label, `label_height` m high and as wide as the
  photo's aspect makes it, its centre half-way up the side and turned `turn_deg` about the axis
  from the robot (0: the label's centre faces the robot); the grasp frame is on the axis half-way
  up, approaching horizontally along the line of sight (the fingers close across the diameter).
- Boxes: a photograph on each of five faces (front, back, left, right, top) and a several-view
  definition of them (each face a planar definition: the photo as its reference image, a pinhole
  with the face's metric size at 0.5 m); the defined front looks `turn_deg` away from the robot
  (180: straight away); the grasp approaches horizontally through the side face that looks most
  towards the robot, square to it, on the line through the box centre, its frame GRASP_IN behind
  that face or at the centre if nearer (the fingers close across the other horizontal side).
Distractors stand on the same table edge, `offset` m to the left (+) or right (-) of the target
along the edge, set back like it.
"""
import math
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_grasp_scenarios import FAULTS, ROOT, TABLE_DEPTH, TABLE_H, fmt, rotvec, upright, world_head  # noqa: E402

# The grasp frame (the target's centre) this far behind the table's front edge: as in the photo
# worlds (9 cm + half a 7 cm box) and can_table; the arm reaches over the edge from a base that
# stands clear of it. The target's nearest point at least ON_TABLE behind the edge.
GRASP_DEPTH = 0.13
ON_TABLE = 0.02
# A box's grasp frame at most this far behind the face it is approached through: the palm's front,
# 6.5 cm behind the gripper frame, stays 2.5 cm clear of it (config/enon.yaml, gripper).
GRASP_IN = 0.04

# Photographs (media/photos, media/labels): path from the repository root.
PHOTOS = {
    "cookie_box": "media/photos/cookie_box.png",
    "butterfly": "media/photos/butterfly_on_leaf.jpg",
    "fruits": "media/photos/fruits_closeup.jpg",
    "aerial_town": "media/photos/aerial_town.jpg",
    "hotel_facade": "media/photos/hotel_facade.jpg",
    "soda_can_label": "media/labels/soda_can_label.png",
}

# A distractor: (name, shape, size numbers, offset along the table edge (m, + left), textures).
CLUTTER = {
    "parcel": ("box", (0.26, 0.20, 0.20), "../../media/boxes/box_side_b.png"),
    "tin": ("cylinder", (0.04, 0.10), "../../media/clutter/clutter_02.png"),
    "sign": ("plane", (0.18, 0.18), "../../media/clutter/clutter_06.png"),
}

WORLDS = [
    dict(name="can_butterfly_clutter", kind="cylinder", photo="butterfly", radius=0.033, height=0.122,
         label_height=0.095, distance=1.6, bearing=20, turn=15, seed=21, noise=2.0, faults="none",
         distractors=[("parcel", 0.36), ("tin", -0.22), ("sign", -0.42)],
         text="a 3.3 cm can with a butterfly photograph as its label (a 64 % wrap) 1.6 m away, 20 deg "
              "to the left, its label turned 15 deg, between a parcel, a tin and a sign"),
    dict(name="bottle_fruits_far", kind="cylinder", photo="fruits", radius=0.045, height=0.24,
         label_height=0.16, distance=2.3, bearing=-15, turn=50, seed=22, noise=2.0, faults="drops",
         distractors=[("tin", 0.30)],
         text="a 4.5 cm bottle with a 16 cm fruit photograph as its label 2.3 m away, 15 deg to the "
              "right, its label's centre turned 50 deg from the robot, a tin beside it, 5 % frame drops"),
    dict(name="can_hotel_wide", kind="cylinder", photo="hotel_facade", radius=0.05, height=0.13,
         label_height=0.10, distance=1.8, bearing=-10, turn=30, seed=31, noise=2.0, faults="none",
         distractors=[("parcel", 0.34)],
         text="a 5 cm can (the widest radius named) 13 cm tall with a hotel photograph as its label "
              "1.8 m away, 10 deg to the right, turned 30 deg, a parcel beside it: grasped 6.5 cm above "
              "the table, which the arm rising from where it hangs must clear"),
    dict(name="box_cookie_turned", kind="box", size=(0.1744, 0.12, 0.16),
         faces=dict(front="cookie_box", back="hotel_facade", left="aerial_town", right="butterfly",
                    top="fruits"),
         distance=1.7, bearing=10, turn=160, seed=23, noise=2.0, faults="none", distractors=[],
         text="a 17 x 12 x 16 cm box of five photographed faces 1.7 m away, 10 deg to the left, "
              "its defined front (the cookie box) turned 160 deg away: its back and one side face "
              "the robot"),
]


def image_size(rel):
    """Width and height of a PNG or baseline/progressive JPEG, read from its header."""
    with open(os.path.join(ROOT, rel), "rb") as f:
        data = f.read()
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return struct.unpack(">II", data[16:24])
    i = 2
    while i < len(data):
        marker, length = data[i + 1], struct.unpack(">H", data[i + 2:i + 4])[0]
        if marker in (0xC0, 0xC1, 0xC2):
            h, w = struct.unpack(">HH", data[i + 5:i + 9])
            return w, h
        i += 2 + length
    raise ValueError(rel + ": no image size found")


def room_and_table(wd, c, psi, near_m):
    """The world's first lines up to `objects:`, with a table whose front edge is perpendicular to
    the grasp's approach (heading psi), GRASP_DEPTH before the grasp frame's origin c (x, y), or
    ON_TABLE before the approach face (near_m before c along the approach) when that is further."""
    back = TABLE_DEPTH / 2 - max(GRASP_DEPTH, near_m + ON_TABLE)
    table_c = [c[0] + back * math.cos(psi), c[1] + back * math.sin(psi)]
    return world_head("make_shape_scenarios.py", wd, table_c, psi)


def distractors(wd, psi):
    """Distractors on the table edge beside the target (the edge perpendicular to heading psi),
    their fronts along it."""
    b = math.radians(wd["bearing"])
    los, left = [math.cos(psi), math.sin(psi)], [-math.sin(psi), math.cos(psi)]
    lines = []
    for name, offset in wd["distractors"]:
        shape, dims, tex = CLUTTER[name]
        c = [wd["distance"] * [math.cos(b), math.sin(b)][i] + offset * left[i] for i in range(2)]
        lines += ["  - name: %s" % name, "    shape: %s" % shape]
        if shape == "box":
            w, h, d = dims
            lines += ["    size_m: [%.2f, %.2f, %.2f]" % (w, h, d),
                      "    faces: {front: %s, top: ../../media/boxes/box_top.png}" % tex,
                      "    side_texture: ../../media/boxes/box_side_a.png"]
            front = [c[i] - d / 2 * los[i] for i in range(2)]
            z = TABLE_H + h / 2
        elif shape == "cylinder":
            r, h = dims
            lines += ["    radius_m: %.3f" % r, "    height_m: %.3f" % h, "    label: %s" % tex,
                      "    label_size_m: [%.4f, %.4f]" % (2 * math.pi * r * 0.6, h * 0.8),
                      "    side_texture: ../../media/clutter/clutter_05.png",
                      "    cap_texture: ../../media/clutter/clutter_04.png"]
            front = [c[i] - r * los[i] for i in range(2)]
            z = TABLE_H + h / 2
        else:
            w, h = dims
            lines += ["    size_m: [%.2f, %.2f]" % (w, h), "    texture: %s" % tex]
            front = c
            z = TABLE_H + h / 2 + 0.01
        lines += ["    pose: {translation: %s, rotation_vector: %s}" % (fmt([front[0], front[1], z]), fmt(rotvec(upright(psi))))]
    return lines


def camera_and_faults(wd):
    lines = ["camera:", "  noise_sigma: %.1f" % wd["noise"], "  exposure_s: 0.01"]
    f = FAULTS[wd["faults"]]
    if f:
        lines += ["faults:"] + ["  %s: %g" % (k, v) for k, v in f.items()] + ['  stuck_joint: ""', "  stuck_after_s: 0"]
    return lines


def write_cylinder(wd):
    w_px, h_px = image_size(PHOTOS[wd["photo"]])
    r, lh = wd["radius"], wd["label_height"]
    lw = lh * w_px / h_px
    assert lw <= 2 * math.pi * r, "the label must not overlap itself"
    name = wd["name"]
    label = "../../" + PHOTOS[wd["photo"]]
    with open(os.path.join(ROOT, "config/objects", name + ".yaml"), "w") as out:
        out.write("# Object definition (detector/object.h, cylinder form): a cylinder of radius %.3f m whose\n"
                  "# label is the real photograph %s (media/README.md), %.4f m of arc\n"
                  "# (%.0f %% of the round) by %.3f m. Written by scripts/make_shape_scenarios.py.\n"
                  % (r, PHOTOS[wd["photo"]], lw, 100 * lw / (2 * math.pi * r), lh))
        out.write("name: %s\nreference_image: %s\ncylinder:\n  radius_m: %.4f\n  label_size_m: [%.4f, %.4f]\n"
                  % (name, label, r, lw, lh))
    b = math.radians(wd["bearing"])
    t = math.radians(wd["turn"])
    phi = b + t  # z_o (into the can at the label's centre) points at this heading
    axis = [wd["distance"] * math.cos(b), wd["distance"] * math.sin(b)]
    origin = [axis[0] - r * math.cos(phi), axis[1] - r * math.sin(phi), TABLE_H + wd["height"] / 2]
    lines = room_and_table(wd, axis, b, r)
    lines += ["  - name: %s" % name,
              "    target: true",
              "    definition: ../objects/%s.yaml" % name,
              "    shape: cylinder",
              "    radius_m: %.4f" % r,
              "    height_m: %.3f" % wd["height"],
              "    label: %s" % label,
              "    label_size_m: [%.4f, %.4f]" % (lw, lh),
              "    side_texture: ../../media/boxes/box_side_a.png",
              "    pose: {translation: %s, rotation_vector: %s}" % (fmt(origin), fmt(rotvec(upright(phi)))),
              # On the axis half-way up, z_g along the line of sight, (sin t, 0, cos t) in o: a
              # turn of t about y_o.
              "    grasp_frame: {translation: [0.0, 0.0, %.4f], rotation_vector: [0.0, %.4f, 0.0]}" % (r, t)]
    lines += distractors(wd, b) + camera_and_faults(wd)
    with open(os.path.join(ROOT, "config/scenarios", name + ".yaml"), "w") as out:
        out.write("\n".join(lines) + "\n")


# A box's faces in its object frame (the front face's: origin at its centre, x along its width,
# y down, z into the box; config/scenarios/README.md): the face frame's rotation vector, its
# centre, and which box dimensions (0 width, 1 height, 2 depth) its texture's width and height span.
def box_faces(W, H, D):
    h = math.pi / math.sqrt(2)
    return {
        "front": ([0, 0, 0], [0, 0, 0], 0, 1),
        "back": ([0, math.pi, 0], [0, 0, D], 0, 1),
        "left": ([0, math.pi / 2, 0], [-W / 2, 0, D / 2], 2, 1),
        "right": ([0, -math.pi / 2, 0], [W / 2, 0, D / 2], 2, 1),
        "top": ([0, h, h], [0, -H / 2, D / 2], 0, 2),
    }


def write_box(wd):
    W, H, D = wd["size"]
    name = wd["name"]
    views = []
    for face, (rv, centre, iw, ih) in box_faces(W, H, D).items():
        rel = PHOTOS[wd["faces"][face]]
        w_px, h_px = image_size(rel)
        wm, hm = wd["size"][iw], wd["size"][ih]
        stem = "%s_%s" % (name, face)
        with open(os.path.join(ROOT, "config/objects", stem + "_camera.yaml"), "w") as out:
            out.write("# Reference camera of %s on the %s face of %s: a pinhole seeing the\n"
                      "# %.4f x %.4f m face frontally at 0.5 m (f = W * 0.5 / width, H * 0.5 / height).\n"
                      "# Written by scripts/make_shape_scenarios.py.\n" % (rel, face, name, wm, hm))
            out.write("image_width: %d\nimage_height: %d\ncamera_name: %s_reference\n" % (w_px, h_px, stem))
            out.write("camera_matrix: {rows: 3, cols: 3, data: [%.4f, 0, %.1f, 0, %.4f, %.1f, 0, 0, 1]}\n"
                      % (w_px * 0.5 / wm, (w_px - 1) / 2, h_px * 0.5 / hm, (h_px - 1) / 2))
            out.write("distortion_model: plumb_bob\n"
                      "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n")
        with open(os.path.join(ROOT, "config/objects", stem + ".yaml"), "w") as out:
            out.write("# The %s face of %s (planar form): the real photograph %s as a %.4f x %.4f m\n"
                      "# face, its own reference image. Written by scripts/make_shape_scenarios.py.\n"
                      % (face, name, rel, wm, hm))
            out.write("name: %s\nreference_image: ../../%s\ncamera: %s_camera.yaml\n" % (stem, rel, stem))
            out.write("reference_pose:\n  translation: [0.0, 0.0, 0.5]\n  rotation_vector: [0.0, 0.0, 0.0]\n")
        views.append("  - definition: %s.yaml\n    oMv: {translation: %s, rotation_vector: %s}\n" % (stem, fmt(centre), fmt(rv)))
    with open(os.path.join(ROOT, "config/objects", name + ".yaml"), "w") as out:
        out.write("# Object definition (detector/object.h, several views): a %.4f x %.2f x %.2f m box of five\n"
                  "# photographed faces; its frame is the front face's (origin at its centre, x along its\n"
                  "# width, y down, z into the box). Written by scripts/make_shape_scenarios.py.\n" % (W, H, D))
        out.write("name: %s\nviews:\n" % name + "".join(views))
    b = math.radians(wd["bearing"])
    t = math.radians(wd["turn"])
    phi = b + t
    los = [math.cos(b), math.sin(b)]
    zo = [math.cos(phi), math.sin(phi)]
    centre = [wd["distance"] * los[0], wd["distance"] * los[1]]
    origin = [centre[0] - D / 2 * zo[0], centre[1] - D / 2 * zo[1], TABLE_H + H / 2]
    # The line of sight in the object frame is (sin t, 0, cos t); approach through the face it
    # meets most squarely: z_g = +-x_o or +-z_o (a turn of `approach` about y_o), y_g = y_o.
    s, c = math.sin(t), math.cos(t)
    approach, half = max([(c, 0.0, D / 2), (-c, math.pi, D / 2), (s, math.pi / 2, W / 2),
                          (-s, -math.pi / 2, W / 2)])[1:]
    psi = phi - approach  # heading of z_g: (sin a, 0, cos a) in o is at phi - a in w
    depth = min(half, GRASP_IN)  # the grasp frame behind the approach face
    zg = [math.cos(psi), math.sin(psi)]
    gp = [centre[0] - (half - depth) * zg[0], centre[1] - (half - depth) * zg[1]]
    g_o = [-(half - depth) * math.sin(approach), 0.0, D / 2 - (half - depth) * math.cos(approach)]
    faces = ", ".join("%s: ../../%s" % (f, PHOTOS[p]) for f, p in wd["faces"].items())
    lines = room_and_table(wd, gp, psi, depth)
    lines += ["  - name: %s" % name,
              "    target: true",
              "    definition: ../objects/%s.yaml" % name,
              "    shape: box",
              "    size_m: [%.4f, %.4f, %.4f]" % (W, H, D),
              "    faces: {%s}" % faces,
              "    side_texture: ../../media/boxes/box_side_a.png",
              "    pose: {translation: %s, rotation_vector: %s}" % (fmt(origin), fmt(rotvec(upright(phi)))),
              "    grasp_frame: {translation: %s, rotation_vector: [0.0, %.4f, 0.0]}" % (fmt(g_o), approach)]
    lines += distractors(wd, psi) + camera_and_faults(wd)
    with open(os.path.join(ROOT, "config/scenarios", name + ".yaml"), "w") as out:
        out.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    for wd in WORLDS:
        (write_cylinder if wd["kind"] == "cylinder" else write_box)(wd)
        print("config/scenarios/%s.yaml" % wd["name"])

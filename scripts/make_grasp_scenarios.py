#!/usr/bin/env python3
"""Writes the varied grasp scenarios (config/scenarios/photo_*.yaml) and the object definitions of
their photographed targets (config/objects/photo_*.yaml + *_camera.yaml) from a few numbers per
world: the target's texture, face width, distance and bearing from the robot, how far it is turned
from the robot's line of sight, distractors, camera degradations and faults. Run from the
repository root: python3 scripts/make_grasp_scenarios.py (plain Python 3, no packages). Geometry conventions: config/scenarios/README.md.

Placement rules (the same for every world, nothing tuned to one): the robot starts at the origin
facing +x; the target's front face centre is `distance_m` away at `bearing_deg` (counter-clockwise
from +x); its front face looks back along the line of sight turned by `turn_deg`; it stands on a
0.72 m table whose front edge is parallel to the face and 9 cm in front of it; the grasp frame is
the box centre (z into the box, x along the face width).
"""
import math
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TABLE_H = 0.72
TABLE_DEPTH, TABLE_WIDTH = 0.70, 1.20
EDGE_TO_FACE = 0.09

# texture file (media/photos), its size in px
PHOTOS = {
    "cookie_box": ("cookie_box.png", 324, 223),
    "butterfly": ("butterfly_on_leaf.jpg", 493, 356),
    "fruits": ("fruits_closeup.jpg", 512, 480),
    "aerial_town": ("aerial_town.jpg", 640, 480),
    "hotel_facade": ("hotel_facade.jpg", 868, 600),
}

FAULTS = {
    "none": None,
    "drops": dict(command_latency_s=0.05, frame_drop_probability=0.05, frame_delay_s=0.02,
                  odom_noise_m_per_m=0.01, odom_noise_rad_per_rad=0.005),
    "heavy": dict(command_latency_s=0.1, frame_drop_probability=0.1, frame_delay_s=0.05,
                  odom_noise_m_per_m=0.02, odom_noise_rad_per_rad=0.01),
}

WORLDS = [
    dict(name="photo_cookie_left", photo="cookie_box", width=0.22, depth=0.07, distance=1.4,
         bearing=35, turn=25, seed=11, noise=2.0, faults="none", distractors=[],
         text="a 22 cm photographed cookie box 1.4 m away, 35 deg to the left, turned 25 deg"),
    dict(name="photo_butterfly_right", photo="butterfly", width=0.18, depth=0.06, distance=1.9,
         bearing=-25, turn=-20, seed=12, noise=3.0, faults="drops", distractors=[],
         text="an 18 cm butterfly photograph 1.9 m away, 25 deg to the right, turned -20 deg, "
              "5 % frame drops, latency"),
    dict(name="photo_fruits_far", photo="fruits", width=0.21, depth=0.08, distance=2.2,
         bearing=-10, turn=30, seed=13, noise=2.0, faults="heavy", distractors=[],
         text="a 21 cm fruit photograph 2.2 m away, 10 deg to the right, turned 30 deg, with the "
              "faults of faults.yaml"),
    dict(name="photo_aerial_small", photo="aerial_town", width=0.16, depth=0.06, distance=1.6,
         bearing=15, turn=-30, seed=14, noise=2.0, faults="drops",
         distractors=[("parcel", "box", 0.28, 0.20, 0.22, 0.32, "../../media/boxes/box_side_b.png")],
         text="a 16 cm aerial photograph 1.6 m away, 15 deg to the left, turned -30 deg, a parcel "
              "beside it, 5 % frame drops"),
    dict(name="photo_hotel_clutter", photo="hotel_facade", width=0.20, depth=0.07, distance=1.7,
         bearing=-40, turn=15, seed=15, noise=2.5, faults="drops",
         distractors=[("packets", "plane", 0.20, 0.15, 0, -0.30,
                       "../../media/photos/cookie_box_in_scene.png"),
                      ("parcel", "box", 0.26, 0.22, 0.20, 0.33, "../../media/boxes/box_side_a.png")],
         text="a 20 cm building photograph 1.7 m away, 40 deg to the right, turned 15 deg, between "
              "a photo of packets and a parcel, 5 % frame drops"),
]


def rotvec(R):
    tr = R[0][0] + R[1][1] + R[2][2]
    a = math.acos(max(-1.0, min(1.0, (tr - 1) / 2)))
    if a < 1e-12:
        return [0.0, 0.0, 0.0]
    s = 2 * math.sin(a)
    axis = [(R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s]
    return [a * x for x in axis]


def upright(phi):
    """Object frame of an upright face whose z (into the object) points at heading phi."""
    c, s = math.cos(phi), math.sin(phi)
    x, y, z = (s, -c, 0.0), (0.0, 0.0, -1.0), (c, s, 0.0)
    return [[x[i], y[i], z[i]] for i in range(3)]


def fmt(v):
    return "[" + ", ".join("%.4f" % x for x in v) + "]"


def world_head(script, wd, table_c, heading):
    """A world's first lines: what it is, the seed, the robot's start, the room and a table whose
    footprint centre is table_c (x, y) and whose x axis points at `heading`; up to `objects:`."""
    return ["# %s. Written by scripts/%s (geometry rules there);" % (wd["text"][0].upper() + wd["text"][1:], script),
            "# format: README.md in this folder.",
            "seed: %d" % wd["seed"],
            "max_duration_s: 120",
            "robot_start: {x: 0.0, y: 0.0, theta: 0.0}",
            "background: ../../media/backgrounds/wall.png",
            "room:",
            "  size_m: [8.0, 8.0]",
            "  centre: [1.5, 0.0]",
            "  floor_texture: ../../media/backgrounds/floor.png",
            "  wall_texture: ../../media/backgrounds/wall.png",
            "  wall_height_m: 2.5",
            "table:",
            "  size_m: [%.2f, %.2f, %.2f]" % (TABLE_DEPTH, TABLE_WIDTH, TABLE_H),
            "  pose: {translation: %s, rotation_vector: %s}" % (fmt([table_c[0], table_c[1], 0.0]), fmt([0, 0, heading])),
            "  texture: ../../media/backgrounds/table_wood.png",
            "objects:"]


def write_object(key, width):
    fname, w_px, h_px = PHOTOS[key]
    f = w_px * 0.5 / width
    name = "photo_" + key
    with open(os.path.join(ROOT, "config/objects", name + "_camera.yaml"), "w") as out:
        out.write("# Reference camera of media/photos/%s: the photo seen as a pinhole image of a %.2f m\n"
                  "# wide plane at 0.5 m (f = W * 0.5 / %.2f px). Written by scripts/make_grasp_scenarios.py.\n"
                  % (fname, width, width))
        out.write("image_width: %d\nimage_height: %d\ncamera_name: %s_reference\n" % (w_px, h_px, name))
        out.write("camera_matrix: {rows: 3, cols: 3, data: [%.4f, 0, %.1f, 0, %.4f, %.1f, 0, 0, 1]}\n"
                  % (f, (w_px - 1) / 2, f, (h_px - 1) / 2))
        out.write("distortion_model: plumb_bob\n"
                  "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n")
    with open(os.path.join(ROOT, "config/objects", name + ".yaml"), "w") as out:
        out.write("# Object definition (detector/object.h): the real photograph media/photos/%s (OpenCV's\n"
                  "# sample data, media/README.md) as a %.2f m wide planar target, its own reference image.\n"
                  "# Written by scripts/make_grasp_scenarios.py.\n" % (fname, width))
        out.write("name: %s\nreference_image: ../../media/photos/%s\ncamera: %s_camera.yaml\n"
                  % (name, fname, name))
        out.write("reference_pose:\n  translation: [0.0, 0.0, 0.5]\n  rotation_vector: [0.0, 0.0, 0.0]\n")


def write_world(wd):
    fname, w_px, h_px = PHOTOS[wd["photo"]]
    width = wd["width"]
    height = width * h_px / w_px
    b = math.radians(wd["bearing"])
    phi = b + math.radians(wd["turn"])
    p = [wd["distance"] * math.cos(b), wd["distance"] * math.sin(b)]
    n = [math.cos(phi), math.sin(phi)]   # into the box, away from the robot
    side = [math.sin(phi), -math.cos(phi)]  # x_o: along the face width
    z = TABLE_H + height / 2
    table_c = [p[0] + (TABLE_DEPTH / 2 - EDGE_TO_FACE) * n[0], p[1] + (TABLE_DEPTH / 2 - EDGE_TO_FACE) * n[1]]
    lines = world_head("make_grasp_scenarios.py", wd, table_c, phi)
    lines += ["  - name: photo_%s" % wd["photo"],
             "    target: true",
             "    definition: ../objects/photo_%s.yaml" % wd["photo"],
             "    shape: box",
             "    size_m: [%.4f, %.4f, %.2f]" % (width, height, wd["depth"]),
             "    faces: {front: ../../media/photos/%s, top: ../../media/boxes/box_top.png}" % fname,
             "    side_texture: ../../media/boxes/box_side_a.png",
             "    pose: {translation: %s, rotation_vector: %s}" % (fmt([p[0], p[1], z]), fmt(rotvec(upright(phi)))),
             "    grasp_frame: {translation: [0.0, 0.0, %.3f], rotation_vector: [0, 0, 0]}" % (wd["depth"] / 2)]
    for (dname, shape, dw, dh, dd, offset, tex) in wd["distractors"]:
        # Beside the target along the table edge, `offset` m along x_o, its face as far back.
        c = [p[0] + offset * side[0], p[1] + offset * side[1]]
        lines += ["  - name: %s" % dname, "    shape: %s" % shape]
        if shape == "box":
            lines += ["    size_m: [%.2f, %.2f, %.2f]" % (dw, dh, dd),
                      "    faces: {front: %s, top: ../../media/boxes/box_top.png}" % tex,
                      "    side_texture: ../../media/boxes/box_side_b.png"]
        else:
            lines += ["    size_m: [%.2f, %.2f]" % (dw, dh), "    texture: %s" % tex]
        lines += ["    pose: {translation: %s, rotation_vector: %s}"
                  % (fmt([c[0], c[1], TABLE_H + dh / 2 + (0.0 if shape == "box" else 0.01)]), fmt(rotvec(upright(phi))))]
    lines += ["camera:", "  noise_sigma: %.1f" % wd["noise"], "  exposure_s: 0.01"]
    f = FAULTS[wd["faults"]]
    if f:
        lines += ["faults:"] + ["  %s: %g" % (k, v) for k, v in f.items()] + ['  stuck_joint: ""', "  stuck_after_s: 0"]
    with open(os.path.join(ROOT, "config/scenarios", wd["name"] + ".yaml"), "w") as out:
        out.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    for wd in WORLDS:
        write_object(wd["photo"], wd["width"])
        write_world(wd)
        print("config/scenarios/%s.yaml" % wd["name"])

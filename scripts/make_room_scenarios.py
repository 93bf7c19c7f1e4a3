#!/usr/bin/env python3
"""Writes the room-sized grasp scenarios (config/scenarios/room_*.yaml): a 10 x 10 m room with
tables and shelves along its walls, distractor boxes on them, and the target 3-6 m from the robot,
behind it or across the room, from a few numbers per world. The targets are the photographed boxes
of scripts/make_grasp_scenarios.py (their definitions, config/objects/photo_*.yaml, are that
script's). Run from the repository root: python3 scripts/make_room_scenarios.py (plain Python 3,
no packages). Geometry conventions: config/scenarios/README.md.

Rules (the same for every world, nothing tuned to one):
- The room is 10 x 10 m centred on the world origin, walls 2.5 m high. The robot starts at
  `start` (x, y, heading).
- Furniture stands with its back 0.25 m from a wall (N: y = +5, S: y = -5, E: x = +5, W: x = -5),
  its front facing the room, its middle at x = `along` (N and S walls) or y = `along` (E, W). A table is 0.70 deep, 1.20
  wide and 0.72 m high; a shelf 0.40 deep, 1.00 wide and 0.85 m high.
- The target is a box on furniture `on`, its photographed front 9 cm behind the front edge,
  `offset` m along the edge from its middle (+ to the left seen from the room), turned `turn_deg`
  from facing straight into the room; grasped at the box centre (as the photo worlds).
- Distractors: a box on another piece of furniture (`dist` entries: furniture index, offset,
  texture, size), placed like the target and facing the room.
The script prints each target's distance and bearing from the robot (the worlds keep 3-6 m).
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_grasp_scenarios import PHOTOS, ROOT, fmt, rotvec, upright  # noqa: E402
from make_shape_scenarios import camera_and_faults  # noqa: E402

ROOM = 10.0
WALL_GAP = 0.25
EDGE_TO_FACE = 0.09
KINDS = {"table": (0.70, 1.20, 0.72), "shelf": (0.40, 1.00, 0.85)}  # depth, width, height
OUT = {"N": (0.0, -1.0), "S": (0.0, 1.0), "E": (-1.0, 0.0), "W": (1.0, 0.0)}  # front normal, into the room
# The target definitions' face widths (config/objects/photo_*_camera.yaml, make_grasp_scenarios.py).
WIDTH = {"cookie_box": 0.22, "butterfly": 0.18, "fruits": 0.21, "aerial_town": 0.16, "hotel_facade": 0.20}

WORLDS = [
    dict(name="room_cookie_behind", photo="cookie_box", depth=0.07, start=(1.0, 0.0, 0.0), seed=41,
         noise=2.0, faults="none", turn=20, on=0, offset=0.2,
         furniture=[("table", "W", 0.8), ("table", "E", -1.5), ("shelf", "N", 1.0), ("table", "S", -2.0)],
         dist=[(1, 0.0, "../../media/boxes/box_side_b.png", (0.26, 0.20, 0.20)),
               (2, 0.1, "../../media/photos/aerial_town.jpg", (0.16, 0.12, 0.06)),
               (3, -0.2, "../../media/photos/hotel_facade.jpg", (0.20, 0.14, 0.07)),
               (0, -0.25, "../../media/boxes/box_side_a.png", (0.20, 0.16, 0.16))],
         text="a 22 cm photographed cookie box on a table 5.2 m behind the robot, turned 20 deg, a "
              "parcel beside it, tables and a shelf with other boxes and photographs round the room"),
    dict(name="room_hotel_shelf", photo="hotel_facade", depth=0.07, start=(0.0, 0.0, -1.2), seed=42,
         noise=2.0, faults="none", turn=-25, on=0, offset=0.0,
         furniture=[("shelf", "N", 2.0), ("table", "W", -1.0), ("table", "E", 2.5), ("table", "S", 1.5)],
         dist=[(1, 0.1, "../../media/photos/cookie_box.png", (0.22, 0.15, 0.07)),
               (2, -0.2, "../../media/boxes/box_side_b.png", (0.26, 0.20, 0.20)),
               (3, 0.0, "../../media/photos/butterfly_on_leaf.jpg", (0.18, 0.13, 0.06))],
         text="a 20 cm photographed hotel facade box on a 0.85 m shelf 4.9 m away across the room, "
              "behind the robot on its left, turned -25 deg, other photographs on the tables"),
    dict(name="room_butterfly_corner", photo="butterfly", depth=0.06, start=(0.0, 1.0, 1.57), seed=43,
         noise=2.5, faults="drops", turn=-10, on=0, offset=-0.15,
         furniture=[("table", "E", -2.5), ("shelf", "N", -2.0), ("table", "W", 1.0), ("table", "S", -1.0)],
         dist=[(0, 0.3, "../../media/photos/aerial_town.jpg", (0.16, 0.12, 0.06)),
               (1, 0.0, "../../media/photos/fruits_closeup.jpg", (0.21, 0.20, 0.08)),
               (2, 0.0, "../../media/boxes/box_side_a.png", (0.20, 0.16, 0.16)),
               (3, 0.2, "../../media/photos/cookie_box.png", (0.22, 0.15, 0.07))],
         text="an 18 cm butterfly photograph box on a table 5.4 m behind the robot on its right, "
              "turned -10 deg, an aerial photograph box beside it, 5 % frame drops and latency"),
    dict(name="room_aerial_across", photo="aerial_town", depth=0.06, start=(-1.5, 0.5, 3.14), seed=52,
         noise=2.5, faults="none", turn=-20, on=1, offset=-0.2,
         furniture=[("table", "W", -1.5), ("table", "E", 0.0), ("shelf", "N", -1.0), ("table", "S", 1.5)],
         dist=[(1, 0.3, "../../media/photos/butterfly_on_leaf.jpg", (0.18, 0.13, 0.06)),
               (2, 0.0, "../../media/photos/fruits_closeup.jpg", (0.21, 0.20, 0.08)),
               (0, 0.0, "../../media/boxes/box_side_a.png", (0.20, 0.16, 0.16))],
         text="a 16 cm aerial photograph box, 12 cm tall, on a table 5.7 m away across the room behind "
              "the robot, turned -20 deg, a butterfly box beside it: the grasp from a base standing "
              "where the arm reaches the pre-grasp pose would put the body against the table edge"),
    dict(name="room_hotel_corner", photo="hotel_facade", depth=0.07, start=(-1.0, 1.0, 0.0), seed=62,
         noise=2.5, faults="drops", turn=-25, on=1, offset=0.4,
         furniture=[("table", "N", -2.0), ("table", "S", -3.5), ("shelf", "E", 3.0), ("table", "W", 0.0)],
         dist=[(0, 0.0, "../../media/photos/fruits_closeup.jpg", (0.21, 0.20, 0.08)),
               (3, 0.2, "../../media/photos/aerial_town.jpg", (0.16, 0.12, 0.06))],
         text="a 20 cm hotel-facade photograph box on a table near the room's south-west corner, "
              "5.9 m away behind the robot on its right, turned -25 deg; 5 % frame drops, latency and "
              "odometry noise: the base's approach goal puts its body within 2 cm of the table"),
    dict(name="room_aerial_shelf", photo="aerial_town", depth=0.06, start=(1.0, -1.0, -1.57), seed=61,
         noise=2.0, faults="none", turn=25, on=0, offset=0.3,
         furniture=[("shelf", "N", 1.5), ("table", "W", -2.0), ("table", "E", 1.5), ("table", "S", -1.5)],
         dist=[(1, 0.0, "../../media/photos/cookie_box.png", (0.22, 0.15, 0.07)),
               (0, -0.25, "../../media/photos/butterfly_on_leaf.jpg", (0.18, 0.13, 0.06)),
               (3, 0.0, "../../media/boxes/box_side_a.png", (0.20, 0.16, 0.16))],
         text="a 16 cm aerial photograph box on a 0.85 m shelf 5.5 m behind the robot, turned 25 deg, "
              "a butterfly box beside it: found from the side, the way to the approach's waypoint "
              "decides whether the head keeps it in view"),
]


def furniture_frame(kind, wall, along):
    """Footprint centre, front normal (into the room), tangent (left seen from the room), size."""
    d, w, h = KINDS[kind]
    n = OUT[wall]
    back = ROOM / 2 - WALL_GAP - d / 2
    c = [-n[0] * back, -n[1] * back]
    tangent = [-n[1], n[0]]
    if wall in ("N", "S"):
        c[0] = along
    else:
        c[1] = along
    return c, n, tangent, (d, w, h)


def box_on(furniture, offset, turn_deg, size):
    """A box's front-face centre and object frame heading (z_o into the box) on furniture."""
    c, n, t, (d, _, h) = furniture
    edge = [c[0] + n[0] * d / 2, c[1] + n[1] * d / 2]
    face = [edge[0] - n[0] * EDGE_TO_FACE + t[0] * offset, edge[1] - n[1] * EDGE_TO_FACE + t[1] * offset]
    phi = math.atan2(-n[1], -n[0]) + math.radians(turn_deg)
    return [face[0], face[1], h + size[1] / 2], phi


def box_lines(name, size, front, side, pos, phi, extra=()):
    return (["  - name: %s" % name] + list(extra) +
            ["    shape: box",
             "    size_m: [%.4f, %.4f, %.2f]" % size,
             "    faces: {front: %s, top: ../../media/boxes/box_top.png}" % front,
             "    side_texture: %s" % side,
             "    pose: {translation: %s, rotation_vector: %s}" % (fmt(pos), fmt(rotvec(upright(phi))))])


def write_world(wd):
    fname, w_px, h_px = PHOTOS[wd["photo"]]
    width = WIDTH[wd["photo"]]
    size = (width, width * h_px / w_px, wd["depth"])
    furniture = [furniture_frame(k, wall, a) for (k, wall, a) in wd["furniture"]]
    sx, sy, sth = wd["start"]
    lines = ["# %s. Written by scripts/make_room_scenarios.py (geometry rules there);"
             % (wd["text"][0].upper() + wd["text"][1:]),
             "# format: README.md in this folder.",
             "seed: %d" % wd["seed"],
             "max_duration_s: 180",
             "robot_start: {x: %.2f, y: %.2f, theta: %.2f}" % (sx, sy, sth),
             "background: ../../media/backgrounds/wall.png",
             "room:",
             "  size_m: [%.1f, %.1f]" % (ROOM, ROOM),
             "  centre: [0.0, 0.0]",
             "  floor_texture: ../../media/backgrounds/floor.png",
             "  wall_texture: ../../media/backgrounds/wall.png",
             "  wall_height_m: 2.5",
             "tables:"]
    for i, ((kind, _, _), (c, n, _, (d, w, h))) in enumerate(zip(wd["furniture"], furniture)):
        lines += ["  - name: %s_%d" % (kind, i),
                  "    size_m: [%.2f, %.2f, %.2f]" % (d, w, h),
                  "    pose: {translation: %s, rotation_vector: %s}"
                  % (fmt([c[0], c[1], 0.0]), fmt([0, 0, math.atan2(-n[1], -n[0])])),
                  "    texture: ../../media/backgrounds/table_wood.png"]
    lines.append("objects:")
    face, phi = box_on(furniture[wd["on"]], wd["offset"], wd["turn"], size)
    # The object frame's origin is the front face's centre (config/scenarios/README.md).
    lines += box_lines("photo_%s" % wd["photo"], size, "../../media/photos/%s" % fname,
                       "../../media/boxes/box_side_a.png", face, phi,
                       ["    target: true", "    definition: ../objects/photo_%s.yaml" % wd["photo"]])
    lines.append("    grasp_frame: {translation: [0.0, 0.0, %.3f], rotation_vector: [0, 0, 0]}" % (wd["depth"] / 2))
    for k, (on, offset, tex, dsize) in enumerate(wd["dist"]):
        pos, dphi = box_on(furniture[on], offset, 0, dsize)
        lines += box_lines("distractor_%d" % k, dsize, tex, "../../media/boxes/box_side_b.png", pos, dphi)
    lines += camera_and_faults(wd)
    with open(os.path.join(ROOT, "config/scenarios", wd["name"] + ".yaml"), "w") as out:
        out.write("\n".join(lines) + "\n")
    dx, dy = face[0] - sx, face[1] - sy
    rel = math.degrees(math.remainder(math.atan2(dy, dx) - sth, 2 * math.pi))
    print("config/scenarios/%s.yaml: target %.2f m away, %.0f deg from the robot's heading"
          % (wd["name"], math.hypot(dx, dy), rel))


if __name__ == "__main__":
    for wd in WORLDS:
        write_world(wd)

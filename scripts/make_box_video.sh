#!/bin/bash
# The two-view definition of the box in media/video/box.mp4 (OpenCV's hand-held box clip):
# planar definitions of its front and top faces from frame 150 (media/video/box_frame150.png),
# joined by make_reference --views. Run from the repository root after building make_reference.
#
# The camera (media/video/box_camera.yaml, f = 650 px) and the box's size (0.25 x 0.0775 x
# 0.1725 m: the width is a guess, the other two follow from the fitted aspect ratios) were
# estimated from the corners labelled in media/video/box_corners.txt: `build/bench/bench_box_video
# --fit-camera` fits a box to them and prints the frame-150 corners used below (docs/results.md
# "Real video: box.mp4"). The back-top-left corner (under the hand) is the fitted box's.
set -euo pipefail
mr=build/app/make_reference
img=media/video/box_frame150.png
cam=media/video/box_camera.yaml
A=102.8,126.1 B=360.7,240.5 C=361.3,328.7 D=125.7,204.8 E=250.1,50.2 F=491.9,121.7
# front: TL, TR, BR, BL = A, B, C, D (W x H); top, turned so that its edge shared with the front
# is at the top: B, A, E, F (W x D) (docs/tools/make_reference.md "Box").
$mr --image $img --camera $cam --corners $A,$B,$C,$D --size 0.25,0.0775 \
    --output config/objects/box_video_front.yaml --check /tmp/box_video_front.png
$mr --image $img --camera $cam --corners $B,$A,$E,$F --size 0.25,0.1725 \
    --output config/objects/box_video_top.yaml --check /tmp/box_video_top.png
$mr --views --box-size 0.25,0.0775,0.1725 --face front=config/objects/box_video_front.yaml \
    --face top=config/objects/box_video_top.yaml --output config/objects/box_video.yaml

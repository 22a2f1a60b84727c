#!/usr/bin/env python3
"""Writes scanner-device/tests/data/mjpeg/: real frames encoded as a webcam's MJPEG would be, by
an independent encoder (OpenCV's libjpeg), for the head's own JPEG decoder to be checked on.

    pip install opencv-python-headless && python3 scripts/make-mjpeg-fixtures.py

- two-plane-off.jpg, two-plane-on.jpg: the real laser-off/laser-on pair 20220331_faa7cdf of
  tests/data/real-two-plane, 4:2:2 (the sampling of UVC webcams' MJPEG), quality 90.
- crop-422-rst.jpg: a 202x150 crop of the laser-on frame around the stripe, 4:2:2 with a
  restart marker every 3 block groups (sizes not multiples of the 16x8 block group).
- crop-420.jpg (4:2:0, quality 75), crop-444.jpg (4:4:4, quality 95), crop-gray.jpg (one
  component): the same crop; crop-411.jpg (4:1:1) and
  crop-progressive.jpg, which the decoder refuses by name.
- crop.png: the crop itself, lossless, to compare the decoded pixels with.
"""
import os
import cv2

root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
src = os.path.join(root, "scanner-device/tests/data/real-two-plane/20220331_faa7cdf")
out = os.path.join(root, "scanner-device/tests/data/mjpeg")
os.makedirs(out, exist_ok=True)

S422, S420, S444, S411 = 0x211111, 0x221111, 0x111111, 0x411111


def write(name, img, quality, sampling=None, rst=0, progressive=False):
    params = [cv2.IMWRITE_JPEG_QUALITY, quality]
    if progressive:
        params += [cv2.IMWRITE_JPEG_PROGRESSIVE, 1]
    if sampling is not None:
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, sampling]
    if rst:
        params += [cv2.IMWRITE_JPEG_RST_INTERVAL, rst]
    ok, buf = cv2.imencode(".jpg", img, params)
    assert ok, name
    with open(os.path.join(out, name), "wb") as f:
        f.write(buf.tobytes())
    print(name, img.shape, len(buf), "bytes")


off = cv2.imread(os.path.join(src, "laser-off.png"), cv2.IMREAD_COLOR)
on = cv2.imread(os.path.join(src, "laser-on.png"), cv2.IMREAD_COLOR)
write("two-plane-off.jpg", off, 90, S422)
write("two-plane-on.jpg", on, 90, S422)
# The crop: around the stripe where it crosses the crease.
gray = cv2.cvtColor(on, cv2.COLOR_BGR2GRAY)
red = on[:, :, 2].astype(int) - on[:, :, 1].astype(int)
row = on.shape[0] // 2
x = int(red[row].argmax())
x0 = max(0, min(on.shape[1] - 202, x - 101))
y0 = row - 75
crop = on[y0:y0 + 150, x0:x0 + 202].copy()
cv2.imwrite(os.path.join(out, "crop.png"), crop)
write("crop-422-rst.jpg", crop, 90, S422, rst=3)
write("crop-420.jpg", crop, 75, S420)
write("crop-444.jpg", crop, 95, S444)
write("crop-411.jpg", crop, 90, S411)
write("crop-progressive.jpg", crop, 90, S422, progressive=True)
write("crop-gray.jpg", cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY), 90)

#!/usr/bin/env python3
"""OpenCV's chessboard calibration of the real webcam photographs, as the reference our tests
compare against (scanner-device/tests/data/real-calibration/).

Usage: scripts/opencv-real-reference.py [DIR]   (default: the test data folder)
Needs opencv-python (pip install opencv-python-headless numpy).
Writes DIR/opencv-corners.csv (image, OpenCV's corner index, x, y after cornerSubPix with
winSize (11, 11)) and DIR/opencv-calibration.txt (the OpenCV version, then fx fy cx cy k1 k2 p1 p2
k3 rms): the procedure the folder's README names (findChessboardCorners (9, 6), cornerSubPix
(11, 11), calibrateCamera with the default model); and the same with winSize (5, 5) as
opencv-corners-5x5.csv and opencv-calibration-5x5.txt.
"""
import glob
import os
import sys

try:
    import cv2
    import numpy as np
except ImportError as e:
    sys.exit(f"needs opencv-python and numpy ({e}); pip install opencv-python-headless numpy")

d = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "scanner-device", "tests", "data", "real-calibration")
cols, rows = 9, 6
objp = np.zeros((cols * rows, 3), np.float32)
objp[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2)
files = sorted(glob.glob(os.path.join(d, "*.jpg")))
found = {}
size = None
for f in files:
    g = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
    size = g.shape[::-1]
    ok, c = cv2.findChessboardCorners(g, (cols, rows))
    if ok:
        found[f] = (g, c)
    else:
        print(f"{os.path.basename(f)}: OpenCV found no board")

# cornerSubPix's winSize is half the window's side: (11, 11) is the README's 23x23 window,
# (5, 5) an 11x11 one that stays inside the squares next to the board's outer corners.
for win, suffix in (((11, 11), ""), ((5, 5), "-5x5")):
    obj, imgs, lines = [], [], ["image,index,x,y"]
    for f, (g, c) in found.items():
        c = cv2.cornerSubPix(g, c.copy(), win, (-1, -1),
                             (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001))
        obj.append(objp)
        imgs.append(c)
        for i, p in enumerate(c.reshape(-1, 2)):
            lines.append(f"{os.path.basename(f)},{i},{p[0]:.4f},{p[1]:.4f}")
    rms, k, dist, _, _ = cv2.calibrateCamera(obj, imgs, size, None, None)
    dist = dist.ravel()
    vals = [k[0, 0], k[1, 1], k[0, 2], k[1, 2], *dist[:5], rms]
    with open(os.path.join(d, f"opencv-corners{suffix}.csv"), "w") as out:
        out.write("\n".join(lines) + "\n")
    with open(os.path.join(d, f"opencv-calibration{suffix}.txt"), "w") as out:
        out.write(f"OpenCV {cv2.__version__}, {len(imgs)} images, cornerSubPix winSize {win}\n")
        out.write(" ".join(f"{v:.6f}" for v in vals) + "\n")
    print(f"OpenCV {cv2.__version__}, cornerSubPix winSize {win}: {len(imgs)} images; fx {vals[0]:.3f} "
          f"fy {vals[1]:.3f} cx {vals[2]:.3f} cy {vals[3]:.3f} k {vals[4]:.5f} {vals[5]:.5f} "
          f"{vals[6]:.6f} {vals[7]:.6f} {vals[8]:.5f} rms {vals[9]:.4f} px")

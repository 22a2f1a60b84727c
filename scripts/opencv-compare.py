#!/usr/bin/env python3
"""OpenCV's calibrateCamera beside ours on the same rendered images.

Usage: scripts/opencv-compare.py DIR   (DIR written by `--example calib_compare`)
Needs opencv-python (pip install opencv-python-headless numpy); skips with a message without it.
Prints a Markdown table: parameter errors against the rig's truth, and the RMS reprojection error.
"""
import glob
import os
import sys
import time

try:
    import cv2
    import numpy as np
except ImportError as e:
    print(f"SKIPPED: OpenCV comparison needs opencv-python and numpy ({e}); "
          "pip install opencv-python-headless numpy")
    sys.exit(0)

d = sys.argv[1] if len(sys.argv) > 1 else "calib-compare"
cols, rows, pitch = 9, 7, 30.0
truth = [float(v) for v in open(os.path.join(d, "truth.txt")).read().split()]
ours_line = [float(v) for v in open(os.path.join(d, "ours.txt")).read().split()]
ours, ours_rms, ours_s = ours_line[:9], ours_line[9], ours_line[10]
files = sorted(glob.glob(os.path.join(d, "grid-*.png")))
objp = np.array([[(c - (cols - 1) / 2) * pitch, (r - (rows - 1) / 2) * pitch, 0.0]
                 for r in range(rows) for c in range(cols)], np.float32)
size = None
obj_cv, img_cv = [], []
for f in files:
    img = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
    size = img.shape[::-1]
    ok, centers = cv2.findCirclesGrid(img, (cols, rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
    if ok:
        obj_cv.append(objp)
        img_cv.append(centers)
# Our detected dots, in our layout order.
pts = {}
for line in open(os.path.join(d, "points.csv")).read().splitlines()[1:]:
    i, k, x, y = line.split(",")
    pts.setdefault(int(i), []).append((int(k), float(x), float(y)))
obj_ours, img_ours = [], []
for i in sorted(pts):
    obj_ours.append(np.array([objp[k] for k, _, _ in pts[i]], np.float32))
    img_ours.append(np.array([[[x, y]] for _, x, y in pts[i]], np.float32))


def calibrate(obj, imgs):
    t = time.time()
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 200, 1e-12)
    rms, k, dist, _, _ = cv2.calibrateCamera(obj, imgs, size, None, None, criteria=crit)
    dist = dist.ravel()
    return [k[0, 0], k[1, 1], k[0, 2], k[1, 2], dist[0], dist[1], dist[2], dist[3], dist[4]], rms, time.time() - t


cv_own = calibrate(obj_cv, img_cv) if len(obj_cv) >= 3 else None
cv_ours = calibrate(obj_ours, img_ours)


def row(name, p, rms, secs, views):
    e = [p[i] - truth[i] for i in range(9)]
    fx = 100 * e[0] / truth[0]
    fy = 100 * e[1] / truth[1]
    pp = (e[2] ** 2 + e[3] ** 2) ** 0.5
    return (f"| {name} | {views} | {fx:+.4f} % | {fy:+.4f} % | {pp:.3f} px | {e[4]:+.5f} | {e[5]:+.4f} | "
            f"{e[6]:+.6f} | {e[7]:+.6f} | {e[8]:+.4f} | {rms:.4f} px | {secs:.2f} s |")


print(f"OpenCV {cv2.__version__}; {len(files)} rendered images, {size[0]}x{size[1]}, sensor noise 2 DN")
print()
print("| solver | views | fx error | fy error | principal point error | k1 error | k2 error | p1 error | p2 error | k3 error | RMS reprojection | time (ours: detection + solve; OpenCV: solve) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
print(row("ours (gray-weighted centroids, disc model)", ours, ours_rms, ours_s, len(pts)))
print(row("OpenCV calibrateCamera on our dots", *cv_ours, len(obj_ours)))
if cv_own:
    print(row("OpenCV findCirclesGrid + calibrateCamera", *cv_own, len(obj_cv)))
else:
    print("| OpenCV findCirclesGrid + calibrateCamera | fewer than 3 grids found | | | | | | | | | | |")

# Chessboards: 10x8 squares of 25 mm, 9x7 inner corners.
chess_files = sorted(glob.glob(os.path.join(d, "chess-*.png")))
if chess_files and os.path.exists(os.path.join(d, "ours-chess.txt")):
    cc, cr, sq = 9, 7, 25.0
    cobj = np.array([[(c - (cc - 1) / 2) * sq, (r - (cr - 1) / 2) * sq, 0.0]
                     for r in range(cr) for c in range(cc)], np.float32)
    obj_ch, img_ch = [], []
    t = time.time()
    for f in chess_files:
        img = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
        ok, corners = cv2.findChessboardCorners(img, (cc, cr))
        if ok:
            corners = cv2.cornerSubPix(img, corners, (11, 11), (-1, -1),
                                       (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4))
            obj_ch.append(cobj)
            img_ch.append(corners)
    oc = [float(v) for v in open(os.path.join(d, "ours-chess.txt")).read().split()]
    print(row("ours, chessboards (Hessian saddles + gradient refinement)", oc[:9], oc[9], oc[10], len(chess_files)))
    if len(obj_ch) >= 3:
        print(row("OpenCV findChessboardCorners + cornerSubPix 11x11 + calibrateCamera", *calibrate(obj_ch, img_ch), len(obj_ch)))
    else:
        print(f"| OpenCV findChessboardCorners | {len(obj_ch)} of {len(chess_files)} boards found | | | | | | | | | | |")

#!/usr/bin/env python3
"""Writes the synthetic CMPMVS DEM fixture (no real sample exists; formats.md §10).

DEM.png: 16-bit grey 4x3, value v = 10000*col + 1000*row, except (0, 0) = 0 (nodata).
DEM.txt: origin (10, 20, -1), X = (4, 0, 0), Y = (0, 1.5, 0), Z = (0, 0, 6.5535),
so height = -1 + v * 1e-4, cells are 1.0 x 0.5, row 0 is the northern row (y in [21, 21.5]).
DEM_ortoPhoto.tiff: an 8-bit RGB 8x6 image (only located by the reader).
bad/: DEM.txt with a rotated box, and one whose W/H disagree with DEM.png.
"""
import os
import cv2
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
row, col = np.mgrid[0:3, 0:4]
v = (10000 * col + 1000 * row).astype(np.uint16)
v[0, 0] = 0
cv2.imwrite(f"{here}/DEM.png", v)
cv2.imwrite(f"{here}/DEM_ortoPhoto.tiff", np.full((6, 8, 3), 128, np.uint8))
txt = ("0: 10.000000 20.000000 -1.000000\r\nX: 4.000000 0.000000 0.000000\r\n"
       "Y: 0.000000 1.500000 0.000000\r\nZ: 0.000000 0.000000 6.553500\r\nW: 4 H: 3\r\n")
with open(f"{here}/DEM.txt", "w", newline="") as f:
    f.write(txt)
for name, t in [("rotated", txt.replace("X: 4.000000 0.000000", "X: 2.828427 2.828427")),
                ("wrong_size", txt.replace("W: 4 H: 3", "W: 5 H: 3"))]:
    os.makedirs(f"{here}/bad/{name}", exist_ok=True)
    cv2.imwrite(f"{here}/bad/{name}/DEM.png", v)
    with open(f"{here}/bad/{name}/DEM.txt", "w", newline="") as f:
        f.write(t)

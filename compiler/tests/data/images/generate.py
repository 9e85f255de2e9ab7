#!/usr/bin/env python3
"""Writes the synthetic image fixtures of this folder (run from anywhere; needs numpy, opencv).

Pixel values follow closed formulas so tests can assert them independently of the decoder:
  grey8.png   8-bit grey 5x4:   v = 10*x + 50*y
  grey16.png  16-bit grey 5x4:  v = 1000*x + 10000*y + 7
  rgb8.png    8-bit RGB 5x4:    R = 40*x, G = 60*y, B = 200 - 30*x
  rgba16.png  16-bit RGBA 5x4:  R = 12000*x, G = 20000*y, B = 3000, A = 65535 - 1000*x
  grey16.tif  16-bit grey TIFF, same values as grey16.png
  rgb8.tif    8-bit RGB TIFF, same values as rgb8.png
  bad/truncated.png  the first 60 bytes of grey8.png; bad/empty.png  0 bytes;
  bad/not_an_image.png  text.
(OpenCV stores colour as BGR(A); the arrays below are reversed accordingly.)
"""
import os
import cv2
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
y, x = np.mgrid[0:4, 0:5]
cv2.imwrite(f"{here}/grey8.png", (10 * x + 50 * y).astype(np.uint8))
g16 = (1000 * x + 10000 * y + 7).astype(np.uint16)
cv2.imwrite(f"{here}/grey16.png", g16)
cv2.imwrite(f"{here}/grey16.tif", g16)
rgb = np.dstack([40 * x, 60 * y, 200 - 30 * x]).astype(np.uint8)
cv2.imwrite(f"{here}/rgb8.png", rgb[:, :, ::-1])
cv2.imwrite(f"{here}/rgb8.tif", rgb[:, :, ::-1])
rgba = np.dstack([12000 * x, 20000 * y, 3000 + 0 * x, 65535 - 1000 * x]).astype(np.uint16)
cv2.imwrite(f"{here}/rgba16.png", rgba[:, :, [2, 1, 0, 3]])
os.makedirs(f"{here}/bad", exist_ok=True)
with open(f"{here}/grey8.png", "rb") as f:
    data = f.read()
with open(f"{here}/bad/truncated.png", "wb") as f:
    f.write(data[:60])
open(f"{here}/bad/empty.png", "wb").close()
with open(f"{here}/bad/not_an_image.png", "w") as f:
    f.write("this is not a PNG\n")

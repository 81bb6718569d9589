"""The board study on circle grids (``edgetruth study board PHOTOS --pattern circles:COLSxROWS[:asymmetric]
--square SIZE``): OpenCV's blob centroids as the reference row, then each edge method's points on every circle, an
ellipse fitted to them and the image of the circle's centre from it (``evaluate.board.circles``, ``corrected``);
per row the calibration, leave-one-image-out RMS, intrinsics and the ellipse residual (docs/board.md, "Circle
grids")."""

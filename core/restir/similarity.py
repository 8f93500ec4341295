"""When two visible points are alike enough to share samples or history.

Temporal reuse (a pixel and its reprojected one), spatial reuse (a pixel and
a neighbour) and the running means (a pixel and the history it reads) accept
another point only if its shading normal and its depth are close to the
pixel's own (the paper's geometric similarity tests)."""

NORMAL_COS_MIN = 0.9        # cosine between the shading normals: about 25 degrees
DEPTH_REL_MAX = 0.1         # depth difference, relative to the pixel's depth

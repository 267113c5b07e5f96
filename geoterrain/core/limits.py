"""The ranges a store's frame may hold, shared by the writer, the reader's checks and the
command line's types (a light module: the CLI reads it without numpy or pyproj).

A horizontal unit of micrometres to 1000 km, a vertical exaggeration and a pixel size in
the same range, and scene coordinates within 10^8 m (2.5 Earth circumferences): beyond
them an option or a unit is wrong, and a store would hold numbers no reader accepts.

Examples
--------
>>> SCENE_LIMIT
100000000.0
"""

UNIT_TO_M_RANGE = (1e-6, 1e6)
Z_SCALE_RANGE = (1e-6, 1e6)
PIXEL_SIZE_RANGE = (1e-6, 1e6)
SCENE_LIMIT = 1e8
#: scene units: a store's tile boxes are rounded outward to multiples of it (the tile
#: table, store/catalog.py); a reader's guess from a box rounds it so too
BOX_STEP = 2.0 ** -12

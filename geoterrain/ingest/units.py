"""Units of a DEM: heights in feet or metres from its CRS, and web-map tiles' georeference.

- :func:`crs_z_units` reads the height unit a CRS implies: its vertical axis
  (a compound CRS) or, failing that, its horizontal unit (a US state plane in
  feet nearly always carries heights in feet).
- :func:`resolve_z_units` turns ``z_units="auto"`` into a unit and warns, naming
  the fix, when a given unit disagrees with the CRS.
- :func:`tile_georeference`: a z/x/y web-map tile (Terrain-RGB, Terrarium) gets
  its Web-Mercator (EPSG:3857) transform; the slippy-map tile → longitude/latitude
  formula is the OSM one, the projection is pyproj's.

Examples
--------
>>> crs_z_units("EPSG:3089")  # Kentucky single zone, US survey feet
('us-ft', 'horizontal')
>>> crs_z_units("EPSG:32633")
('m', 'horizontal')
>>> tile_from_path("tiles/12/3637/1612.png")
(12, 3637, 1612)
>>> t, _ = tile_georeference(0, 0, 0, 256, 256)
>>> round(t[0], 2)  # metres (Web Mercator) per pixel at zoom 0
156543.03
"""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path

from geoterrain.exceptions import UsageError

log = logging.getLogger("geoterrain")

UNIT_NAMES = {"m": "metres", "ft": "international feet", "us-ft": "US survey feet"}
_FACTORS = {"m": 1.0, "ft": 0.3048, "us-ft": 1200.0 / 3937.0}


def unit_of_factor(f: float) -> str | None:
    """The unit name ('m', 'ft', 'us-ft') whose metres per unit is ``f``, if any."""
    for k, v in _FACTORS.items():
        if abs(f - v) < 1e-7:
            return k
    return None


def crs_z_units(crs) -> tuple[str | None, str | None]:
    """(unit, where) of the heights a CRS implies: where is 'vertical' or 'horizontal'.

    (None, None) for a geographic CRS without a vertical axis, or no CRS.
    """
    if crs is None:
        return None, None
    from pyproj import CRS

    c = CRS.from_user_input(crs)
    for sub in c.sub_crs_list or [c]:
        for ax in sub.axis_info:
            if ax.direction in ("up", "down"):
                return unit_of_factor(ax.unit_conversion_factor), "vertical"
    if c.is_projected and c.axis_info:
        return unit_of_factor(c.axis_info[0].unit_conversion_factor), "horizontal"
    return None, None


def resolve_z_units(z_units: str, crs_wkt: str | None, src: str = "the DEM") -> str:
    """The height unit to use: ``z_units``, or the CRS's when it is "auto" (else metres).

    Logs a warning that names the fix when the CRS suggests feet and nothing says
    so, or when the given unit disagrees with the CRS's.
    """
    if z_units != "auto" and z_units not in _FACTORS:
        raise UsageError(f"unknown vertical unit {z_units!r}; use auto, "
                         f"{', '.join(_FACTORS)}")
    found, where = crs_z_units(crs_wkt)
    if z_units == "auto":
        if found is None:
            return "m"
        if found != "m" and where == "horizontal":
            log.warning("%s: heights taken as %s, the CRS's horizontal unit; if they are "
                        "metres, pass z_units='m' (--z-units m)", src, UNIT_NAMES[found])
        return found
    if found is not None and found != z_units:
        log.warning("%s: heights given in %s but the CRS's %s unit is %s; check z_units "
                    "(--z-units %s, or auto to follow the CRS)", src, UNIT_NAMES[z_units],
                    where, UNIT_NAMES[found], found)
    return z_units


# ------------------------------------------------------------------ web tiles
_TILE_PATH = re.compile(r"(\d{1,2})[/\\_-](\d+)[/\\_-](\d+)\.(png|webp)$", re.I)


def parse_tile(s: str) -> tuple[int, int, int]:
    """``"z/x/y"`` → (z, x, y), checked against the zoom level."""
    m = re.fullmatch(r"\s*(\d+)/(\d+)/(\d+)\s*", s or "")
    if not m:
        raise UsageError(f"a tile is z/x/y such as 12/3637/1612, got {s!r}")
    z, x, y = (int(v) for v in m.groups())
    if not (0 <= z <= 30 and x < 2**z and y < 2**z):
        raise UsageError(f"tile {s}: x and y must be below 2^z = {2**min(z, 30)}")
    return z, x, y


def tile_from_path(path: str | Path) -> tuple[int, int, int] | None:
    """(z, x, y) when the path ends in z/x/y.png (or z_x_y.png), else None."""
    m = _TILE_PATH.search(Path(path).as_posix())
    if not m:
        return None
    z, x, y = (int(v) for v in m.groups()[:3])
    return (z, x, y) if x < 2**z and y < 2**z else None


def _lonlat(z: int, x: float, y: float) -> tuple[float, float]:
    n = 2.0**z  # OSM slippy-map tile numbers → longitude, latitude (degrees)
    lon = x / n * 360.0 - 180.0
    lat = math.degrees(math.atan(math.sinh(math.pi * (1 - 2 * y / n))))
    return lon, lat


def tile_georeference(z: int, x: int, y: int, width: int, height: int
                      ) -> tuple[tuple[float, ...], str]:
    """(affine (a, b, c, d, e, f), CRS WKT) of a ``width`` × ``height`` z/x/y tile in
    EPSG:3857 (x = a·col + c, y = e·row + f)."""
    from pyproj import CRS, Transformer

    tr = Transformer.from_crs("EPSG:4326", "EPSG:3857", always_xy=True)
    w, n = tr.transform(*_lonlat(z, x, y))
    e, s = tr.transform(*_lonlat(z, x + 1, y + 1))
    return ((e - w) / width, 0.0, w, 0.0, (s - n) / height, n), CRS("EPSG:3857").to_wkt()

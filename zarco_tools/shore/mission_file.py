"""Mission files for ``zarco shore mission FILE``: TOML waypoints or a GeoJSON LineString.

TOML (``.toml``)::

    name = "survey A"          # optional
    speed_mps = 1.0            # optional (default 1.0; --speed overrides)
    waypoints = [[41.1850, -8.7050], [41.1859, -8.7050], [41.1859, -8.7044]]

A ``[mission]`` table as in the vessel configuration (``frame = "geodetic"``)
is read the same way.  GeoJSON (``.geojson``, ``.json``): a LineString, a
Feature with one, or the first LineString of a FeatureCollection;
coordinates are ``[lon, lat]`` as GeoJSON has them; ``properties.name`` and
``properties.speed_mps`` are used when present.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

from zarco_core.paths import PathError, read_text


class MissionFileError(ValueError):
    pass


def _check(wps: list[list[float]], where: str) -> list[list[float]]:
    if len(wps) < 2:
        raise MissionFileError(f"{where}: need at least 2 waypoints, got {len(wps)}")
    for i, w in enumerate(wps):
        lat, lon = w
        if not (math.isfinite(lat) and math.isfinite(lon) and -90 <= lat <= 90
                and -180 <= lon <= 180):
            raise MissionFileError(f"{where}: waypoint {i} is not a latitude, longitude: {w}")
    return wps


def _pairs(raw: Any, where: str, lonlat: bool) -> list[list[float]]:
    if not isinstance(raw, list):
        raise MissionFileError(f"{where}: expected a list of coordinates")
    out = []
    for i, p in enumerate(raw):
        if not (isinstance(p, list) and len(p) >= 2
                and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in p[:2])):
            raise MissionFileError(f"{where}: point {i} must be "
                                   + ("[lon, lat]" if lonlat else "[lat_deg, lon_deg]"))
        a, b = float(p[0]), float(p[1])
        out.append([b, a] if lonlat else [a, b])
    return out


def load_mission(path: str | Path) -> dict[str, Any]:
    """The ``mission`` command's arguments from a file: ``waypoints`` [[lat, lon], ...],
    ``speed_mps`` and ``name`` (when the file gives them)."""
    p = Path(path)
    try:
        text = read_text(p)
    except PathError as exc:
        raise MissionFileError(str(exc)) from None
    out: dict[str, Any] = {"name": p.stem}
    if p.suffix.lower() in (".geojson", ".json"):
        try:
            doc = json.loads(text)
        except ValueError as exc:
            raise MissionFileError(f"{path}: not JSON: {exc}") from None
        geom, props = _linestring(doc, str(path))
        out["waypoints"] = _check(_pairs(geom.get("coordinates"), str(path), True), str(path))
        if isinstance(props.get("name"), str):
            out["name"] = props["name"]
        if isinstance(props.get("speed_mps"), (int, float)):
            out["speed_mps"] = float(props["speed_mps"])
        return out
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MissionFileError(f"{path}: not TOML: {exc}") from None
    if isinstance(d.get("mission"), dict):
        d = d["mission"]
        if d.get("frame", "geodetic") != "geodetic":
            raise MissionFileError(f"{path}: mission.frame must be \"geodetic\" (latitude, "
                                   "longitude) for a mission sent from shore")
    if "waypoints" not in d:
        raise MissionFileError(f"{path}: no waypoints = [[lat_deg, lon_deg], ...]")
    out["waypoints"] = _check(_pairs(d["waypoints"], f"{path}: waypoints", False), str(path))
    if "speed_mps" in d:
        out["speed_mps"] = float(d["speed_mps"])
    if isinstance(d.get("name"), str):
        out["name"] = d["name"]
    return out


def _linestring(doc: Any, where: str) -> tuple[dict[str, Any], dict[str, Any]]:
    if not isinstance(doc, dict):
        raise MissionFileError(f"{where}: not a GeoJSON object")
    kind = doc.get("type")
    if kind == "LineString":
        return doc, {}
    if kind == "Feature":
        g = doc.get("geometry") or {}
        if isinstance(g, dict) and g.get("type") == "LineString":
            props = doc.get("properties") or {}
            return g, props if isinstance(props, dict) else {}
    if kind == "FeatureCollection":
        for f in doc.get("features") or []:
            try:
                return _linestring(f, where)
            except MissionFileError:
                continue
    raise MissionFileError(f"{where}: no GeoJSON LineString in it")

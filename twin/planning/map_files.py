"""The files a map is made of, and the SHA-256 of their content.

A scenario that references its map (``[space.map]``) keeps this hash, so that a map
edited, replaced or read with another image is refused by name rather than giving another
floor under the same scenario, and so that the scenario's digest covers the map's content.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import yaml

from calib.io.text import read_text, yaml_load
from twin.planning.floor_map import MapError
from twin.planning.maps import MAP_SUFFIXES

CHUNK = 1 << 20
"""Bytes read at a time, for hashing a large map."""


def map_files(path: str | Path) -> list[Path]:
    """The files of the map ``path`` its reader reads, in order: the file itself, then a ROS
    map's image, or a glTF's external buffers.

    Raises:
        MapError: ``path`` is not a file.
    """
    path = Path(path)
    if not path.is_file():
        raise MapError(path, "the map file does not exist")
    out = [path]
    kind = MAP_SUFFIXES.get(path.suffix.lower())
    try:
        if kind == "ros":
            doc = yaml_load(read_text(path))
            image = doc.get("image") if isinstance(doc, dict) else None
            if isinstance(image, str) and image.strip():
                out.append(path.parent / image)
        elif path.suffix.lower() == ".gltf":
            doc = json.loads(path.read_text(encoding="utf-8"))
            for buffer in doc.get("buffers", []) if isinstance(doc, dict) else []:
                uri = buffer.get("uri") if isinstance(buffer, dict) else None
                if isinstance(uri, str) and not uri.startswith("data:"):
                    out.append(path.parent / uri)
    except (OSError, ValueError, yaml.YAMLError):
        pass  # the reader names what is wrong with the file
    return [p for p in out if p.is_file()]


def map_sha256(path: str | Path) -> str:
    """SHA-256 (64 hex digits) of the map's content: the bytes of :func:`map_files` one
    after the other (for a ROS map, ``cat map.yaml map.pgm | sha256sum``).

    Raises:
        MapError: ``path`` is not a file, or cannot be read.
    """
    digest = hashlib.sha256()
    for part in map_files(path):
        try:
            with part.open("rb") as f:
                while chunk := f.read(CHUNK):
                    digest.update(chunk)
        except OSError as exc:
            raise MapError(part, f"cannot read the map: {exc}") from None
    return digest.hexdigest()

"""Scene folders: finding them by name, the files a scene references and its content hash.

A built scene is a folder with ``scene.xml`` (Mitsuba XML), the ``meshes/*.ply`` it references and
the ``spec.toml`` it was built from. :func:`scene_content_hash` is the one definition of a scene's
identity: the builder prints it and the trace cache keys on it. Pure Python (no ray tracer).
"""

from __future__ import annotations

import hashlib
import os
import xml.etree.ElementTree as ET
from pathlib import Path

__all__ = ["DEFAULT_SCENE", "SCENES_DIR", "SceneError", "scene_content_hash", "scene_directory", "scene_references"]

#: The repository's scene folder (``scenes/`` beside the packages).
SCENES_DIR = Path(__file__).resolve().parent.parent.parent / "scenes"
#: Name of the built-in default hall.
DEFAULT_SCENE = "paper_hall"


class SceneError(ValueError):
    """A scene file that cannot be loaded or traced; the message names the file and the fix."""


def _parse_xml(xml_path: str) -> ET.Element:
    if not os.path.exists(xml_path):
        raise SceneError(f"scene file {xml_path} does not exist; check the path (scenes live in scenes/<name>/)")
    if not os.path.isfile(xml_path):
        raise SceneError(f"scene file {xml_path} is not a regular file; pass the path of the Mitsuba XML")
    try:
        return ET.parse(xml_path).getroot()
    except ET.ParseError as exc:
        raise SceneError(
            f"scene file {xml_path} is not well-formed XML ({exc}); fix the XML at that position "
            "or regenerate the scene"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"scene file {xml_path} cannot be read: {exc}") from None


def _check_inside(xml_path: str, folder: str, value: str, resolved: str) -> None:
    """Refuse a reference that leaves the scene's folder (``..``, an absolute path, a symlink out)."""
    real_folder = os.path.realpath(folder)
    real = os.path.realpath(resolved)
    if os.path.isabs(value) or os.path.commonpath([real_folder, real]) != real_folder:
        how = ("is an absolute path" if os.path.isabs(value)
               else f"resolves to {real}" + (" through a symbolic link" if real != resolved else ""))
        raise SceneError(
            f"scene file {xml_path} references {value!r}, which {how}, outside the scene folder {folder}; "
            "a scene may only use files inside its own folder: copy the mesh into it (e.g. meshes/) "
            "and reference it by a relative path"
        )


def scene_references(xml_path: str | os.PathLike[str]) -> list[tuple[str, str]]:
    """Files referenced by a Mitsuba XML scene, in document order.

    Parameters
    ----------
    xml_path : path-like
        The scene's XML file.

    Returns
    -------
    list of (str, str)
        ``(value as written, resolved absolute path)`` for every ``<string name="filename">``
        and every ``filename=`` attribute (``<include>``), relative paths resolved against the
        XML's folder.

    Raises
    ------
    SceneError
        The XML is missing or malformed, a reference uses ``$parameter`` substitution, a
        referenced file does not exist, or a reference leaves the XML's folder (an absolute
        path, ``..`` or a symbolic link resolving outside it): a scene never reads a file
        outside its own folder.
    """
    xml_path = os.path.abspath(os.fspath(xml_path))
    root = _parse_xml(xml_path)
    folder = os.path.dirname(xml_path)
    refs: list[tuple[str, str]] = []
    for elem in root.iter():
        values = []
        if elem.tag == "string" and elem.get("name") == "filename" and elem.get("value") is not None:
            values.append(elem.get("value"))
        if elem.tag != "string" and elem.get("filename") is not None:
            values.append(elem.get("filename"))
        for value in values:
            if "$" in value:
                raise SceneError(
                    f"scene file {xml_path} references {value!r} through $parameter substitution, which "
                    "risloc-rt cannot resolve to hash the scene; write the file name out"
                )
            resolved = os.path.normpath(os.path.join(folder, value))
            _check_inside(xml_path, folder, value, resolved)
            if not os.path.isfile(resolved):
                raise SceneError(
                    f"scene file {xml_path} references {value!r}, but {resolved} does not exist; "
                    "restore the mesh or fix the filename (relative paths are relative to the XML's folder)"
                )
            refs.append((value, resolved))
    return refs


def scene_content_hash(xml_path: str | os.PathLike[str]) -> str:
    """SHA-256 (hex) over the XML's bytes and the bytes of every file it references.

    Parameters
    ----------
    xml_path : path-like
        The scene's XML file.

    Notes
    -----
    The digest covers, in order, the XML bytes, then for each reference in document order its name
    as written, its length and its bytes (each part length-prefixed, so no two scenes can collide
    by shifting bytes between parts). Moving the scene folder does not change it; editing any byte
    of the XML or of a mesh does.
    """
    xml_path = os.path.abspath(os.fspath(xml_path))
    refs = scene_references(xml_path)
    digest = hashlib.sha256(b"risloc-rt scene v1\0")

    def part(data: bytes) -> None:
        digest.update(len(data).to_bytes(8, "little"))
        digest.update(data)

    with open(xml_path, "rb") as f:
        part(f.read())
    for value, resolved in refs:
        part(value.encode("utf-8"))
        with open(resolved, "rb") as f:
            part(f.read())
    return digest.hexdigest()


def scene_directory(scene: str | Path) -> Path:
    """A scene folder from a name in ``scenes/`` or a path (folder or its ``scene.xml``)."""
    p = Path(scene)
    if p.is_file() and p.suffix == ".xml":
        return p.parent
    if p.is_dir():
        return p
    named = SCENES_DIR / str(scene)
    if named.is_dir():
        return named
    available = sorted(d.name for d in SCENES_DIR.iterdir() if (d / "scene.xml").is_file()) if SCENES_DIR.is_dir() else []
    raise FileNotFoundError(f"no scene {str(scene)!r}: not a folder, a scene.xml, or a name in {SCENES_DIR} "
                            f"(available: {', '.join(available) or 'none'})")

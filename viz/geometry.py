"""The vehicle's visual geometry, read from its URDF (boxes, cylinders, spheres).

Parsed with ``xml.etree`` rather than through a URDF/mesh library so the viewer needs
no dependency beyond viser: pinquad's vehicle descriptions only use primitive shapes.
Fixed joints are composed into one body frame; any other joint is drawn at its zero
position (a quadcopter is one rigid body).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import quat_wxyz_from_rotation, rotation_from_euler
from pinquad.core.params import VEHICLES

Array = NDArray[np.float64]

DEFAULT_COLOR = (150, 150, 160)

# Real vehicles are 10-25 cm across and fly metres: without enlarging them they vanish
# at trajectory scale. Tuned so each reads at about 1 m wide (default_scale caps them
# on small scenes).
VEHICLE_SCALE = {"paper": 5.0, "crazyflie21": 15.0}


class UrdfError(ValueError):
    """The URDF cannot be drawn; the message names the file and the element."""


@dataclass(frozen=True)
class VisualPart:
    """One primitive of the vehicle in the body frame.

    kind: "box" (dims = x, y, z sizes [m]), "cylinder" (dims = radius, length [m],
    axis along its local z, as in URDF) or "sphere" (dims = radius [m]).
    position (3,) [m] and wxyz (4,) place it in the body frame; rgb 0-255; opacity 0-1.
    """

    name: str
    kind: str
    dims: tuple[float, ...]
    position: Array
    wxyz: Array
    rgb: tuple[int, int, int]
    opacity: float


def _floats(text: str | None, n: int, default: float, where: str) -> Array:
    if text is None:
        return np.full(n, default)
    try:
        vals = np.asarray([float(v) for v in text.split()], dtype=float)
    except ValueError:
        raise UrdfError(f"{where}: {text!r} is not {n} numbers") from None
    if vals.shape != (n,):
        raise UrdfError(f"{where}: {text!r} is not {n} numbers")
    return vals


def _origin(elem: ET.Element | None, where: str) -> tuple[Array, Array]:
    """Translation and rotation matrix of an ``<origin xyz rpy>`` element. URDF's
    fixed-axis roll-pitch-yaw is the same Rz Ry Rx product pinquad uses for Euler
    angles, so the conventions module converts it."""
    if elem is None:
        return np.zeros(3), np.eye(3)
    xyz = _floats(elem.get("xyz"), 3, 0.0, f"{where} origin xyz")
    rpy = _floats(elem.get("rpy"), 3, 0.0, f"{where} origin rpy")
    return xyz, rotation_from_euler(rpy)


def _rgba(material: ET.Element | None, named: dict[str, tuple[float, ...]]
          ) -> tuple[tuple[int, int, int], float]:
    if material is None:
        return DEFAULT_COLOR, 1.0
    color = material.find("color")
    if color is not None and color.get("rgba"):
        rgba = tuple(float(v) for v in color.get("rgba", "").split())
    else:
        rgba = named.get(material.get("name", ""), ())
    if len(rgba) != 4:
        return DEFAULT_COLOR, 1.0
    rgb = tuple(int(round(255 * min(max(c, 0.0), 1.0))) for c in rgba[:3])
    return (rgb[0], rgb[1], rgb[2]), float(rgba[3])


def vehicle_parts(urdf_file: str | Path) -> tuple[VisualPart, ...]:
    """Every primitive visual of the URDF, posed in the root link's frame."""
    urdf_file = Path(urdf_file)
    try:
        root = ET.parse(urdf_file).getroot()
    except (OSError, ET.ParseError) as exc:
        raise UrdfError(f"{urdf_file}: not a readable URDF ({exc})") from None
    named = {}
    for mat in root.findall("material"):
        color = mat.find("color")
        if color is not None and color.get("rgba"):
            named[mat.get("name", "")] = tuple(float(v) for v in color.get("rgba", "").split())

    links = {link.get("name", ""): link for link in root.findall("link")}
    children: dict[str, list[tuple[str, Array, Array]]] = {}
    child_names = set()
    for joint in root.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            raise UrdfError(f"{urdf_file}: joint {joint.get('name')!r} lacks parent or child")
        xyz, rot = _origin(joint.find("origin"), f"{urdf_file}: joint {joint.get('name')!r}")
        children.setdefault(parent.get("link", ""), []).append((child.get("link", ""), xyz, rot))
        child_names.add(child.get("link", ""))
    roots = [name for name in links if name not in child_names]
    if not roots:
        raise UrdfError(f"{urdf_file}: no root link (every link is some joint's child)")

    parts: list[VisualPart] = []
    # Depth-first from the root, composing each fixed joint's placement.
    stack = [(roots[0], np.zeros(3), np.eye(3))]
    while stack:
        name, pos, rot = stack.pop()
        link = links.get(name)
        if link is None:
            continue
        for k, visual in enumerate(link.findall("visual")):
            where = f"{urdf_file}: link {name!r} visual {k}"
            v_xyz, v_rot = _origin(visual.find("origin"), where)
            geom = visual.find("geometry")
            shape = None if geom is None or len(geom) == 0 else geom[0]
            if shape is None:
                continue
            if shape.tag == "box":
                kind, dims = "box", tuple(_floats(shape.get("size"), 3, 0.0, where))
            elif shape.tag == "cylinder":
                kind = "cylinder"
                dims = (float(shape.get("radius", 0)), float(shape.get("length", 0)))
            elif shape.tag == "sphere":
                kind, dims = "sphere", (float(shape.get("radius", 0)),)
            else:
                # Meshes would need a mesh loader; pinquad's vehicles do not use them.
                continue
            rgb, alpha = _rgba(visual.find("material"), named)
            part_rot = rot @ v_rot
            parts.append(VisualPart(
                name=f"{name}_{k}", kind=kind, dims=dims, position=pos + rot @ v_xyz,
                wxyz=quat_wxyz_from_rotation(part_rot), rgb=rgb, opacity=alpha,
            ))
        for child, j_xyz, j_rot in children.get(name, []):
            stack.append((child, pos + rot @ j_xyz, rot @ j_rot))
    if not parts:
        raise UrdfError(f"{urdf_file}: no box, cylinder or sphere visual to draw")
    return tuple(parts)


def body_radius(parts: tuple[VisualPart, ...]) -> float:
    """Largest distance [m] of any part's centre plus its size from the body origin."""
    reach = 0.0
    for p in parts:
        size = max(p.dims) if p.kind != "box" else 0.5 * float(np.linalg.norm(p.dims))
        reach = max(reach, float(np.linalg.norm(p.position)) + size)
    return reach


def default_scale(vehicle: str, parts: tuple[VisualPart, ...], scene_radius: float | None = None
                  ) -> float:
    """Display magnification of the vehicle.

    The tuned value for known vehicles (else whatever makes it about 1 m across), but
    never so large that the drawn vehicle reaches beyond a fifth of ``scene_radius`` [m]
    (half the diagonal of the flown region): a Crazyflie flying a 2 m scenario at x15
    would hide its own path.
    """
    radius = body_radius(parts)
    if vehicle in VEHICLE_SCALE:
        scale = VEHICLE_SCALE[vehicle]
    else:
        scale = 0.5 / radius if radius > 0 else 1.0
    if scene_radius is not None and scene_radius > 0 and radius > 0:
        scale = min(scale, max(0.2 * scene_radius / radius, 1.0))
    return scale


def stand_in(mass: float | None) -> tuple[str, float]:
    """The vehicle drawn for a log that names none: the known vehicle (``VEHICLES``)
    nearest in mass ratio to ``mass`` [kg] and its size factor (mass / its mass)^(1/3)
    [-] (equal density: a quad of that mass); the paper's at its size without a mass."""
    if mass is None or not np.isfinite(mass) or mass <= 0:
        return "paper", 1.0
    name = min(VEHICLES, key=lambda v: abs(np.log(mass / VEHICLES[v].mass)))
    return name, float((mass / VEHICLES[name].mass) ** (1.0 / 3.0))


def resized(parts: tuple[VisualPart, ...], factor: float) -> tuple[VisualPart, ...]:
    """``parts`` with every size and offset multiplied by ``factor`` [-] (the vehicle's
    own size, unlike the display magnification)."""
    return tuple(VisualPart(p.name, p.kind, tuple(factor * d for d in p.dims),
                            factor * p.position, p.wxyz, p.rgb, p.opacity) for p in parts)

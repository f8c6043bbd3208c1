"""Scenes: obstacles, the ground, the payload, sampling bounds, start and goal (design.md 6-7).

A :class:`SceneSpec` is plain data (pydantic, frozen); scene files are TOML in
``flycrane/world/scenes/`` and load by name (``load_scene("rescue")``) or by path. Orientations
of shapes use the project's tilt-and-torsion angles ``(phi, theta, sigma)`` (design.md s.3;
a yaw alone is ``(0, 0, yaw)``). World shapes are in the world frame, payload shapes in the
platform frame. Meshes come from an STL/OBJ file (resolved relative to the scene file; not
allowed in scenes sent over HTTP) or inline vertices and faces.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import tomllib
from collections.abc import Iterable
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from flycrane.errors import FieldProblem, InputError
from flycrane.model.kinematics import matrix_from_tilt_torsion
from flycrane.model.system_spec import SystemSpec, problems_from_validation_error
from flycrane.quantities import (
    MAX_LENGTH,
    Configuration,
    Length,
    Mass,
    NonNegativeLength,
    Orientation,
    Point,
)
from flycrane.user_files import MAX_MESH_BYTES, read_text, regular_file
from flycrane.world.memo import SharedCache, read_only

StrictIndex = Annotated[int, Field(ge=0, strict=True)]
#: Every scene schema: numbers finite (flycrane.quantities), unknown fields refused.
_CONFIG = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

#: Where the scenes shipped with the package live.
SCENES_DIR = Path(__file__).parent / "scenes"


class SceneError(InputError):
    """A scene description is invalid or cannot be found; names the field and the reason."""


class _Shape(BaseModel):
    model_config = _CONFIG

    name: str = Field(
        "", max_length=200, description="used in collision reports; default: kind and index"
    )
    center: Point = (0.0, 0.0, 0.0)
    rotation: Orientation = Field((0.0, 0.0, 0.0), description="(phi, theta, sigma) [rad]")

    @property
    def axes(self) -> NDArray[np.float64]:
        """The shape's orientation in its parent's frame: a rotation matrix, the shape's
        axes as its columns."""
        return matrix_from_tilt_torsion(np.array(self.rotation, dtype=float))


class Box(_Shape):
    kind: Literal["box"] = "box"
    size: tuple[Length, Length, Length] = Field(description="edge lengths x, y, z [m]")


class Cylinder(_Shape):
    kind: Literal["cylinder"] = "cylinder"
    radius: Length
    height: Length = Field(description="along the shape's own z axis [m]")


class Sphere(_Shape):
    kind: Literal["sphere"] = "sphere"
    radius: Length


class Mesh(_Shape):
    kind: Literal["mesh"] = "mesh"
    file: str | None = Field(None, description="STL/OBJ path, relative to the scene file")
    vertices: tuple[Point, ...] | None = None
    faces: tuple[tuple[StrictIndex, StrictIndex, StrictIndex], ...] | None = None
    scale: Length = 1.0

    @model_validator(mode="after")
    def _one_source(self) -> Mesh:
        inline = self.vertices is not None or self.faces is not None
        if (self.file is None) == (not inline):
            raise ValueError("give either file, or vertices and faces")
        if self.vertices is not None or self.faces is not None:
            if not self.vertices or not self.faces:
                raise ValueError("vertices and faces must both be non-empty")
            top = len(self.vertices)
            if any(not 0 <= i < top for face in self.faces for i in face):
                raise ValueError(f"faces index vertices 0..{top - 1} only")
            _check_extent(self.scale * np.asarray(self.vertices, float))
        return self

    def triangles(self, base_dir: Path | None) -> tuple[np.ndarray, np.ndarray]:
        """(vertices (V, 3) scaled, faces (F, 3)) from the file or the inline data; both
        read-only (a file's faces are shared: :func:`_mesh_file` parses a file once).

        Raises
        ------
        SceneError
            The file cannot be read as a triangle mesh, or its vertices are not finite or
            lie beyond ``MAX_LENGTH`` once scaled (field ``mesh.file``).
        """
        if self.vertices is not None and self.faces is not None:
            vertices = self.scale * np.asarray(self.vertices, float)
            return read_only(vertices), read_only(np.asarray(self.faces, int))
        path = Path(str(self.file)) if base_dir is None else base_dir / str(self.file)
        try:
            raw, faces = _mesh_file(regular_file(path, "mesh.file", MAX_MESH_BYTES))
            vertices = self.scale * raw
            _check_extent(vertices)
        except InputError as error:
            raise SceneError(error.about(path).problems) from None
        # IndexError: trimesh's OBJ reader on a face that names a vertex the file lacks
        except (OSError, ValueError, AttributeError, IndexError) as error:
            raise SceneError([FieldProblem("mesh.file", f"{path}: {error}")]) from None
        return read_only(vertices), faces


#: Parsed mesh files kept per process (:func:`_mesh_file`), in bytes of arrays in all (a file
#: of MAX_MESH_BYTES parses to at most ~130 MB).
MESH_FILE_CACHE_BYTES = 512 * 2**20

_mesh_files: SharedCache[tuple[np.ndarray, np.ndarray]] = SharedCache(
    MESH_FILE_CACHE_BYTES, lambda arrays: arrays[0].nbytes + arrays[1].nbytes
)


def _mesh_file(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) float, faces (F, 3) int) of a mesh file as trimesh reads it,
    unscaled and read-only; parsed once per process for the same bytes and suffix (what
    trimesh reads by): a task builds several checkers of one scene, each of which takes its
    meshes' triangles more than once, and reading a file costs little beside parsing it.

    Raises what ``trimesh.load_mesh`` raises (nothing is cached then).
    """
    import trimesh

    data, kind = path.read_bytes(), path.suffix.lower().lstrip(".")
    key = (hashlib.blake2b(data, digest_size=20).digest(), kind)
    cached = _mesh_files.get(key)
    if cached is None:
        mesh = trimesh.load_mesh(io.BytesIO(data), file_type=kind)
        vertices = read_only(np.array(mesh.vertices, dtype=float))
        cached = (vertices, read_only(np.array(mesh.faces, dtype=int)))
        _mesh_files.put(key, cached)
    return cached


def _check_extent(vertices: np.ndarray) -> None:
    """Refuse vertices (V, 3) that are not finite or lie beyond MAX_LENGTH (a collision
    body whose size overflows is never checked: flycrane.quantities)."""
    if not np.all(np.isfinite(vertices)):
        raise ValueError("vertices must be finite numbers")
    extent = float(np.abs(vertices).max(initial=0.0))
    if extent > MAX_LENGTH:
        raise ValueError(
            f"vertices must lie within {MAX_LENGTH:g} m of the shape's origin once scaled "
            f"(one is {extent:.3g} m away)"
        )


Shape = Annotated[Box | Cylinder | Sphere | Mesh, Field(discriminator="kind")]


class Payload(BaseModel):
    """What the platform carries: shapes in the platform frame, and the mass properties."""

    model_config = _CONFIG

    shapes: tuple[Shape, ...] = ()
    mass: Mass | None = Field(None, description="platform plus payload [kg]; None: system's")
    com_offset: Point | None = Field(None, description="c' [m], platform frame; None: system's")


class Bounds(BaseModel):
    """Where the planner samples: a box for P, a largest tilt, an alpha range."""

    model_config = _CONFIG

    position_low: Point
    position_high: Point
    max_tilt: float = Field(0.6, gt=0.0, le=math.pi, description="largest theta [rad]", strict=True)
    alpha_low: float = Field(0.3, description="[rad]", strict=True)
    alpha_high: float = Field(1.8, description="[rad]", strict=True)
    sigma_low: float = Field(
        -math.pi, ge=-2 * math.pi, description="torsion range [rad]", strict=True
    )
    sigma_high: float = Field(
        math.pi, le=2 * math.pi, description="torsion range [rad]", strict=True
    )

    @model_validator(mode="after")
    def _ordered(self) -> Bounds:
        low, high = np.array(self.position_low), np.array(self.position_high)
        axes = [a for a, lo, hi in zip("xyz", low, high, strict=True) if not lo < hi]
        if axes:
            raise ValueError(f"position_low must be below position_high on {', '.join(axes)}")
        if not 0.0 <= self.alpha_low < self.alpha_high <= math.pi:
            raise ValueError("need 0 <= alpha_low < alpha_high <= pi")
        if not 0.0 < self.sigma_high - self.sigma_low <= 2 * math.pi:
            raise ValueError("need sigma_low < sigma_high, at most 2 pi apart")
        return self


class CollisionSettings(BaseModel):
    """Sizes of the robot's collision bodies (design.md s.6 defaults)."""

    model_config = _CONFIG

    cable_radius: Length = 0.01
    drone_radius: Length = 0.3
    min_drone_separation: Length = Field(1.0, description="drone centre distance [m]")
    platform_thickness: Length = Field(0.02, description="thin prism through B_i [m]")
    cable_clearance_at_platform: NonNegativeLength = Field(
        0.05, description="cable length near b_i not checked against the payload [m]"
    )
    obstacle_clearance: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="least distance from every robot body to the obstacles and the ground "
        "[m]: obstacles are grown by it and the ground raised, so flown deviations of up "
        "to this size cannot touch them",
        strict=True,
    )


#: Most obstacles a scene holds: each is a collision object of its own (memory and time
#: per check grow with their number), where a mesh holds any number of faces.
MAX_OBSTACLES = 10_000


class SceneSpec(BaseModel):
    """A complete planning scene."""

    model_config = _CONFIG

    name: str = Field("scene", max_length=200)
    description: str = Field("", max_length=10_000)
    obstacles: tuple[Shape, ...] = Field(
        (),
        max_length=MAX_OBSTACLES,
        description=f"at most {MAX_OBSTACLES}: a site of more parts is given as meshes",
    )
    ground: bool = Field(True, description="the plane z = 0 is an obstacle", strict=True)
    payload: Payload = Field(default_factory=Payload)
    bounds: Bounds
    start: Configuration
    goal: Configuration
    collision: CollisionSettings = Field(default_factory=CollisionSettings)

    def obstacle_name(self, index: int) -> str:
        """How collision reports name obstacle ``index`` (its name, else kind and number)."""
        shape = self.obstacles[index]
        return shape.name or f"{shape.kind} {index + 1}"

    def without(self, names: Iterable[str]) -> SceneSpec:
        """The scene without the obstacles of these names (``"ground"``: without the
        ground), e.g. where touching them is intended."""
        names = set(names)
        kept = tuple(o for i, o in enumerate(self.obstacles) if self.obstacle_name(i) not in names)
        return self.model_copy(
            update={"obstacles": kept, "ground": self.ground and "ground" not in names}
        )

    def grown_obstacles(self) -> tuple[Shape, ...]:
        """The obstacles grown by ``collision.obstacle_clearance`` on every side (a box, a
        cylinder's radius and height, a sphere's radius): every point within the clearance
        of an obstacle lies in its grown shape (boxes and cylinders also add their corners).
        Meshes are returned as they are: the checkers keep the clearance from their faces
        (a margin, :mod:`flycrane.world.collision_kernel`)."""
        c = self.collision.obstacle_clearance
        if c == 0:
            return self.obstacles
        grow = {
            "box": lambda o: {"size": tuple(v + 2 * c for v in o.size)},
            "cylinder": lambda o: {"radius": o.radius + c, "height": o.height + 2 * c},
            "sphere": lambda o: {"radius": o.radius + c},
            "mesh": lambda o: {},
        }
        return tuple(o.model_copy(update=grow[o.kind](o)) for o in self.obstacles)

    def system_spec(self, base: SystemSpec | None = None) -> SystemSpec:
        """The system carrying this scene's payload (its mass and centre of mass, if set)."""
        base = base or SystemSpec()
        update: dict[str, object] = {}
        if self.payload.mass is not None:
            update["platform_mass"] = self.payload.mass
        if self.payload.com_offset is not None:
            update["com_offset"] = self.payload.com_offset
        return SystemSpec.model_validate({**base.model_dump(by_alias=True), **update})


def scene_from_dict(data: dict, source: str | None = None) -> SceneSpec:
    """Validate a mapping as a scene, raising :class:`SceneError` naming the field."""
    try:
        return SceneSpec.model_validate(data)
    except ValidationError as error:
        raise SceneError(problems_from_validation_error(error), source) from None


def list_scenes() -> list[str]:
    """Names of the scenes shipped with the package."""
    return sorted(p.stem for p in SCENES_DIR.glob("*.toml"))


def scene_path(name_or_path: str | Path) -> Path:
    """The file of a scene given by name (shipped) or by path."""
    path = Path(name_or_path)
    if path.suffix == "" and (SCENES_DIR / f"{path.name}.toml").exists():
        return SCENES_DIR / f"{path.name}.toml"
    if not path.exists():
        known = ", ".join(list_scenes())
        raise SceneError([FieldProblem("scene", f"no scene {str(name_or_path)!r}; known: {known}")])
    return path


def load_scene(name_or_path: str | Path) -> tuple[SceneSpec, Path]:
    """Load a scene by name or path (a ``.json`` file as JSON, as the service's scene
    presets give it, any other as TOML); returns it with the directory its mesh files
    live in."""
    path = scene_path(name_or_path)
    json_file = path.suffix.lower() == ".json"
    try:
        text = read_text(path)
        scene = scene_from_dict(json.loads(text) if json_file else tomllib.loads(text), str(path))
    except InputError as error:  # the file unreadable, or a field of the scene
        raise SceneError(error.problems, str(path)) from None
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as error:
        form = "JSON" if json_file else "TOML (a scene file is .toml, or .json)"
        raise SceneError([FieldProblem("file", f"not valid {form}: {error}")], str(path)) from None
    return scene, path.parent

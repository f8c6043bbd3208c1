"""/v1/presets: the named systems and scenes a task may refer to."""

from __future__ import annotations

from fastapi import APIRouter

from flycrane.model.system_spec import SYSTEM_PRESETS
from flycrane.world.scene import list_scenes, load_scene

router = APIRouter(prefix="/v1/presets", tags=["presets"])


@router.get("/systems")
def systems() -> dict[str, dict]:
    """Preset name -> full system description."""
    return {
        name: spec.model_dump(mode="json", by_alias=True) for name, spec in SYSTEM_PRESETS.items()
    }


@router.get("/scenes")
def scenes() -> dict[str, dict]:
    """Preset name -> full scene description (obstacles, payload, bounds, start, goal)."""
    return {name: load_scene(name)[0].model_dump(mode="json") for name in list_scenes()}

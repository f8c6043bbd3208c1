"""The API's documentation, served from this server: ``/docs`` (Swagger UI, vendored in
``service/static/swagger-ui/``, its README says which version and license) and its files.

Open to everyone, as ``/openapi.json`` is: neither carries task data. ``create_app`` leaves
both out with ``FLYCRANE_API_DOCS=false``. The page runs only this server's scripts
(:func:`service.security.page_policy`).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import FileResponse, HTMLResponse

from service.errors import ArtifactNotFoundError
from service.security import CSP, page_policy

router = APIRouter(include_in_schema=False)

STATIC_DIR = Path(__file__).resolve().parents[2] / "static"
PAGE = "docs.html"


@cache
def _files() -> frozenset[str]:
    """The names the page may load (paths relative to STATIC_DIR), nothing else."""
    return frozenset(
        path.relative_to(STATIC_DIR).as_posix()
        for path in STATIC_DIR.rglob("*")
        if path.is_file() and path.name != PAGE
    )


@router.get("/docs", response_class=HTMLResponse)
def docs() -> HTMLResponse:
    """Swagger UI on this server's ``openapi.json``."""
    page = (STATIC_DIR / PAGE).read_text(encoding="utf-8")
    return HTMLResponse(page, headers={CSP: page_policy(page)})


@router.get("/docs/static/{name:path}")
def docs_file(name: str) -> FileResponse:
    """A file of the docs page (Swagger UI's script and styles, its license)."""
    if name not in _files():
        raise ArtifactNotFoundError(f"the docs have no file {name!r}")
    return FileResponse(STATIC_DIR / name)

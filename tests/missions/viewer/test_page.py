"""The viewer's HTML: data carried inline and safely, modules by URL (served) or as data:
URLs (standalone), only the viewer's own files served. The pages are run in a real browser
by tests/service/test_viewer.py."""

from __future__ import annotations

import base64
import html.parser
import json

from missions.viewer.page import (
    MODULES,
    STATIC_DIR,
    served_page,
    standalone_page,
    static_file,
)

#: A document with what a page needs to be built (the browser tests use real ones).
DOCUMENT = {"title": "</script><script>alert('x')</script> & co", "planned": {"time": [0.0]}}


class Scripts(html.parser.HTMLParser):
    """The page's <script> elements: type, src and text."""

    def __init__(self) -> None:
        super().__init__()
        self.scripts: list[dict] = []
        self.title = ""
        self._in: str | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "script":
            self.scripts.append({**dict(attrs), "text": ""})
        self._in = tag

    def handle_endtag(self, tag):
        self._in = None

    def handle_data(self, data):
        if self._in == "script":
            self.scripts[-1]["text"] += data
        elif self._in == "title":
            self.title += data


def parse(page: str) -> Scripts:
    parser = Scripts()
    parser.feed(page)
    return parser


def by_type(parser: Scripts, kind: str) -> list[dict]:
    return [s for s in parser.scripts if s.get("type") == kind]


def test_served_page_carries_the_document_and_loads_modules_by_url():
    parser = parse(served_page(DOCUMENT, "../static/", "../list"))
    (data,) = by_type(parser, "application/json")
    assert json.loads(data["text"]) == DOCUMENT  # the title's markup stays data
    assert parser.title.startswith(DOCUMENT["title"])
    (imports,) = by_type(parser, "importmap")
    assert json.loads(imports["text"])["imports"] == {
        name: f"../static/{path}" for name, path in MODULES.items()
    }
    (main,) = by_type(parser, "module")
    assert main["src"] == "../static/viewer.js"
    for name, path in MODULES.items():
        assert static_file(path) == STATIC_DIR / path, name


def test_standalone_page_needs_nothing_beside_it():
    page = standalone_page(DOCUMENT)
    parser = parse(page)
    (data,) = by_type(parser, "application/json")
    assert json.loads(data["text"]) == DOCUMENT
    imports = json.loads(by_type(parser, "importmap")[0]["text"])["imports"]
    assert set(imports) == set(MODULES)
    prefix = "data:text/javascript;base64,"
    sources = {}
    for name, url in imports.items():
        assert url.startswith(prefix), name
        sources[name] = base64.b64decode(url[len(prefix) :]).decode()
    # Every module as vendored, but three.module.js importing the core by its map name.
    for name, path in MODULES.items():
        vendored = (STATIC_DIR / path).read_text(encoding="utf-8")
        if name == "three":
            assert "'./three.core.js'" in vendored and "'./three.core.js'" not in sources[name]
            assert sources[name] == vendored.replace("'./three.core.js'", "'three/core'")
        else:
            assert sources[name] == vendored
    (main,) = by_type(parser, "module")
    assert (
        "src" not in main
        and main["text"].strip() == (STATIC_DIR / "viewer.js").read_text(encoding="utf-8").strip()
    )
    assert "<link" not in page.replace('<link rel="icon" href="data:,">', "")  # styles inline
    assert "MIT License" in page


def test_static_files_are_only_the_viewers():
    assert static_file("viewer.js") == STATIC_DIR / "viewer.js"
    assert static_file("vendor/uplot/LICENSE") == STATIC_DIR / "vendor/uplot/LICENSE"
    for name in ("../page.py", "vendor/../../page.py", "/etc/passwd", "missing.js", ""):
        assert static_file(name) is None, name

"""The documentation cannot go stale: generated pages equal their sources, links resolve.

* docs/scenes.md is what impact_fenics.docs_pages writes from the key table the scene
  reader checks by, and docs/performance.md what it writes from docs/bench.json: a key
  added to the reader, or a new benchmark, without `make docs` fails here.
* The key table and the code agree: every generator of the table exists, and each
  generator's parameters are those of its function.
* Every relative link of README.md, docs/, meshes/ and benchmarks/ resolves to a file
  (and to a heading or an anchor of it, when the link names one).
* docs/architecture.md lists every module of the package and no module that is not
  there; meshes/README.md lists every mesh generator of impact_fenics/meshing.py.

Pure file checks: the same on every rank.
"""
import glob
import inspect
import json
import os
import re

import pytest

from impact_fenics import docs_pages, meshing
from impact_fenics.scene_keys import GENERATORS, REQUIRED_PARAMS, SECTIONS

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _read(rel: str) -> str:
    with open(os.path.join(ROOT, rel), encoding="utf-8") as f:
        return f.read()


def test_scene_reference_is_generated_from_the_key_table():
    assert _read("docs/scenes.md") == docs_pages.scenes_page(), "run `make docs`"


def test_performance_page_is_generated_from_the_benchmark_json():
    with open(docs_pages.BENCH_JSON) as f:
        bench = json.load(f)
    assert _read("docs/performance.md") == docs_pages.performance_page(bench), "run `make docs`"


def test_every_key_of_the_table_is_on_the_page():
    page = _read("docs/scenes.md")
    for section in SECTIONS.values():
        for key in section.keys:
            if key.kind not in ("table", "tables", "array"):
                assert f"| `{key.name}` |" in page, (section.toml, key.name)


def test_the_generators_of_the_table_are_the_functions():
    """Each generator of the key table is a function with exactly the table's parameters
    (quad_bar: radius, length, n_r, all required; rod_on_anvil: those and the anvil's
    radius and depth, the function's arguments but n_z, which the reader derives)."""
    from impact_fenics import quad_meshes

    mesh = SECTIONS["mesh"]
    for gen in GENERATORS:
        table = {k.name for k in mesh.keys if gen in k.groups}
        if gen == "quad_bar":
            assert table == set(REQUIRED_PARAMS["quad_bar"])
            continue
        if gen == "rod_on_anvil":
            params = set(inspect.signature(quad_meshes.rod_on_anvil).parameters)
            assert table == params - {"comm", "n_z"}
            continue
        params = set(inspect.signature(getattr(meshing, gen)).parameters) - {"comm"}
        assert table == params, gen


# ------------------------------------------------------------------------------- links

PAGES = ["README.md", "meshes/README.md", "benchmarks/README.md"] + sorted(
    os.path.relpath(p, ROOT) for p in glob.glob(os.path.join(ROOT, "docs", "*.md")))
LINK = re.compile(r"(?<!\!)\[[^\]]*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)")


def _anchors(text: str) -> set[str]:
    """GitHub's anchors of a Markdown page: its headings' slugs and explicit ids."""
    out = set(re.findall(r'<a id="([^"]+)"', text))
    for line in text.splitlines():
        m = re.match(r"#+\s+(.*)", line)
        if m:
            title = re.sub(r"[`*_]", "", m.group(1)).strip().lower()
            out.add(re.sub(r"[^\w\- ]", "", title).replace(" ", "-"))
    return out


@pytest.mark.parametrize("page", PAGES)
def test_relative_links_resolve(page):
    text = _read(page)
    here = os.path.dirname(os.path.join(ROOT, page))
    for m in LINK.finditer(text):
        target = m.group(1) or m.group(2)
        if re.match(r"[a-z]+:", target):  # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        full = os.path.normpath(os.path.join(here, path)) if path else os.path.join(ROOT, page)
        assert os.path.exists(full), f"{page}: {target} does not exist"
        if anchor and full.endswith(".md"):
            with open(full, encoding="utf-8") as f:
                assert anchor in _anchors(f.read()), f"{page}: no anchor #{anchor} in {path}"


# ------------------------------------------------------------------------------- maps

def _entries(page: str) -> dict[str, str]:
    """The entries of the map's code blocks: {name at the line's start: its text, with
    the indented lines that continue it}."""
    entries: dict[str, str] = {}
    name = None
    for block in re.findall(r"```\n(.*?)```", page, re.S):
        for line in block.splitlines():
            if line and not line[0].isspace():
                name, _, text = line.partition(" ")
                entries[name] = text
            elif name is not None:
                entries[name] += " " + line.strip()
    return entries


def test_architecture_lists_every_module():
    entries = _entries(_read("docs/architecture.md"))
    package = os.path.join(ROOT, "impact_fenics")
    for path in glob.glob(os.path.join(package, "**", "*.py"), recursive=True):
        rel = os.path.relpath(path, package)
        folder, name = os.path.split(rel)
        if name == "__init__.py":
            continue
        if folder:
            text = entries.get(folder + "/", "")
            assert re.search(rf"\b{re.escape(name)}\b", text), f"{rel} is not in its folder's entry"
        else:
            assert name in entries or any(name in t for t in entries.values()), \
                f"docs/architecture.md does not list {rel}"
    for name in entries:
        where = [os.path.join(package, name), os.path.join(ROOT, name)]
        assert any(os.path.exists(w) for w in where), f"{name} is listed, not there"
        if name.endswith("/") and os.path.isdir(os.path.join(package, name)):
            for listed in re.findall(r"(?<![/\w])(\w+\.py)\b", entries[name]):
                assert os.path.isfile(os.path.join(package, name, listed)), \
                    f"{name}{listed} is listed, not there"


def test_meshes_readme_lists_every_generator():
    page = _read("meshes/README.md")
    generators = [name for name, fn in inspect.getmembers(meshing, inspect.isfunction)
                  if fn.__module__ == meshing.__name__ and not name.startswith("_")
                  and inspect.signature(fn).return_annotation in ("TaggedMesh",
                                                                   meshing.TaggedMesh)]
    assert {"bar", "coaxial_bars", "punch_block"} <= set(generators)  # the search finds them
    for name in generators + list(GENERATORS):
        assert re.search(rf"\b{name}\b", page), f"meshes/README.md does not list {name}"

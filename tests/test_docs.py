"""The documentation holds: README within 10 KB, every relative link and image in README and
docs/ resolves, the README's first scene is the file it names, and every ```console block of
README and docs/ runs (lines starting with `$ `, or every line if none does). A block may be
exempt only with a reason beside it: `<!-- docs-test: skip (reason) -->` on the line before.

The commands run as written from the repository root, with two substitutions so that the test
is quick and leaves the checkout clean: `results/` becomes a temporary folder, and `silo run`
gets its stages shortened (two layers in 0.5 s, 0.2 s of storage, 0.5 s of discharge: coarse
settings of the same scene; the full run is what README promises a user, ~2 min on 2 cores)."""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import subprocess_env

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"(?P<before>[^\n]*)\n```(?P<lang>\w*)\n(?P<body>.*?)\n```", re.S)
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
SKIP = re.compile(r"<!-- docs-test: skip \((?P<reason>[^)]{10,})\) -->")
SHORT = ["--set", "fill.layers=2", "--set", "fill.duration=0.5", "--set", "store.duration=0.2",
         "--set", "discharge.duration=0.5"]

pytestmark = pytest.mark.serial  # runs commands (some under mpirun) in subprocesses: once is enough


def blocks(path: Path, lang: str):
    text = "\n" + path.read_text()
    for m in FENCE.finditer(text):
        if m["lang"] == lang:
            yield m["before"], m["body"]


def commands(body: str) -> list[str]:
    lines = [ln for ln in body.splitlines() if ln.strip()]
    prompted = [ln[2:] for ln in lines if ln.startswith("$ ")]
    return prompted or [ln.split("#")[0].strip() for ln in lines]


def test_readme_is_short():
    assert (ROOT / "README.md").stat().st_size <= 10 * 1024


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_links_and_images_resolve(doc):
    text = re.sub(r"```.*?```", "", doc.read_text(), flags=re.S)  # code is not a link
    missing = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue  # external (not checked offline) or an in-page anchor
        if not (doc.parent / target.split("#")[0]).exists():
            missing.append(target)
    assert not missing, f"{doc.name}: {missing}"


def test_readme_first_scene_is_the_shipped_file():
    toml = [body for _, body in blocks(ROOT / "README.md", "toml")]
    shipped = (ROOT / "demos" / "scenes" / "first_silo.toml").read_text().strip()
    assert shipped in [t.strip() for t in toml]


def _console_blocks():
    for doc in DOCS:
        for before, body in blocks(doc, "console"):
            yield pytest.param(doc, before, body, id=f"{doc.relative_to(ROOT)}:{commands(body)[0][:40]}")


@pytest.mark.parametrize("doc,before,body", list(_console_blocks()))
def test_console_blocks_run(doc, before, body, tmp_path):
    if "docs-test: skip" in before:
        assert SKIP.search(before), f"{doc.name}: a skipped block needs its reason: {before!r}"
        return
    env = subprocess_env()
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    for line in commands(body):
        argv = [a.replace("results/", f"{tmp_path}/") for a in shlex.split(line)]
        if "silo" in argv and argv[argv.index("silo") + 1] == "run":
            argv += SHORT
        done = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"{doc.name}: `{line}` failed:\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"

"""The docs site (issue 26): mkdocs.yml builds with warnings as errors (every page in the nav,
every link and anchor found), the README stays a front page of at most 15 KB whose links into
docs/ hold, and the codes table lives on the codes page."""
import os
import re
import subprocess
import sys

import pytest

from helpers import DOCS, REPO


def test_the_site_builds_strict(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("material")  # (the theme; CI installs .[all], which holds the docs extra)
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(REPO / "mkdocs.yml"),
                          "-d", str(tmp_path / "site")], cwd=REPO, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert (tmp_path / "site" / "codes" / "index.html").is_file()
    built = {p.relative_to(tmp_path / "site").parent.as_posix() for p in (tmp_path / "site").rglob("index.html")}
    for page in DOCS.rglob("*.md"):  # every page of docs/ is in the site
        assert page.relative_to(DOCS).with_suffix("").as_posix() in built | {"index"}, page


def test_the_readme_is_a_front_page_whose_links_hold():
    readme = (REPO / "README.md").read_bytes()
    assert len(readme) <= 15_000, f"README.md is {len(readme):,} bytes: move text into docs/"
    text = readme.decode()
    links = re.findall(r"\]\(((?:docs|models)/[^)#]+)(?:#([^)]+))?\)", text)
    assert len(links) >= 15
    for path, anchor in links:
        target = REPO / path
        assert target.is_file(), path
        if anchor:  # a heading of that page, as mkdocs' toc writes its id
            ids = {re.sub(r"[^\w\s-]", "", h.lower()).strip().replace(" ", "-")
                   for h in re.findall(r"^#+ (.+)$", target.read_text(), re.M)}
            assert anchor in ids, (path, anchor)
    assert "<!-- codes: generated" not in text  # (the table is the codes page's: docs/codes.md)

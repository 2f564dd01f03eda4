"""The docs site builds strict (`mkdocs build --strict`, mkdocs.yml): a link to a page
or an anchor that does not exist, or a page left out of the nav, fails the suite. The
README's links (outside the site) resolve too, and it stays short."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
README_MAX_LINES = 250


def test_the_site_builds_strict(tmp_path: Path) -> None:
    """About 1.6 s of CPU; the site goes to a temporary directory."""
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet",
                        "--site-dir", str(tmp_path / "site")], cwd=REPO, capture_output=True,
                       text=True, timeout=300,
                       env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert r.returncode == 0, r.stdout + r.stderr
    assert (tmp_path / "site" / "tutorial" / "index.html").is_file()


def test_every_page_is_in_the_nav_and_every_nav_entry_a_page() -> None:
    """What the strict build checks, said without building: each docs/ page is in the
    nav once, and the nav names no page that does not exist."""
    nav = re.findall(r":\s+(\S+\.md)$", (REPO / "mkdocs.yml").read_text(), re.M)
    pages = sorted(str(p.relative_to(REPO / "docs")) for p in (REPO / "docs").rglob("*.md"))
    assert sorted(nav) == pages, (set(nav) ^ set(pages))


def test_the_readme_is_short_and_its_links_resolve() -> None:
    text = (REPO / "README.md").read_text()
    assert len(text.splitlines()) <= README_MAX_LINES
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
    assert links, "the README maps the docs"
    missing = [link for link in links
               if not link.startswith("http") and not (REPO / link).is_file()]
    assert not missing, missing
    # every page of the site is reachable from the README's map
    pages = {f"docs/{p.relative_to(REPO / 'docs')}" for p in (REPO / "docs").rglob("*.md")}
    assert pages - {"docs/index.md"} <= set(links), pages - set(links)

"""The README and docs/ point only at what exists: every relative link's file and anchor, and
every repository path named in backticks.

Broken versions these catch (each tried once): a heading renamed in docs/motion.md ("What it
showed") while docs/techniques.md still links to #what-it-showed; a page moved
(docs/cost-policy.md renamed, the README's and the pages' links left); a file moved
(experiments/scale_quick.yaml renamed while three pages name it); a slug that keeps
punctuation (test_slug_follows_github).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from helpers import ROOT

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^(```|~~~).*?^\1", re.M | re.S)
LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
CODE = re.compile(r"`([^`\n]+)`")
HEADING = re.compile(r"^#{1,6}\s+(.+?)\s*#*\s*$", re.M)
# backticked paths that name what a run writes or a placeholder, not a file of the repository
NOT_REPOSITORY = ("DIR/", "results/", "~/", "$", ".venv/", ".cache/", ".make/", ".benchmarks/",
                  "http://", "https://", "/")
PLACEHOLDER = re.compile(r"[<>*{}=\s]|\.\.\.")


def prose(text: str) -> str:
    """The page without its fenced code blocks (examples, trees, shell sessions)."""
    return FENCE.sub("", text)


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: inline markup dropped, lowercase, punctuation other than
    '-' and '_' dropped, each space a '-'."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link keeps its text
    text = re.sub(r"[^\w\- ]", "", text.lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every heading's anchor, with GitHub's -1, -2 suffixes for repeated ones."""
    seen: dict[str, int] = {}
    found = set()
    for heading in HEADING.findall(prose(page.read_text())):
        base = slug(heading)
        n = seen.get(base, 0)
        found.add(base if n == 0 else f"{base}-{n}")
        seen[base] = n + 1
    return found


def broken_links(page: Path) -> list[str]:
    broken = []
    for target in LINK.findall(prose(page.read_text())):
        if re.match(r"[a-z]+:", target):  # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.exists():
            broken.append(f"{target}: no file {path}")
        elif anchor and file.suffix == ".md" and anchor not in anchors(file):
            broken.append(f"{target}: no heading with anchor #{anchor} in {file.name}")
    return broken


def named_paths(page: Path) -> list[str]:
    """Backticked repository paths in the page's prose: a '/' inside, no placeholder."""
    names = []
    for code in CODE.findall(prose(page.read_text())):
        if "/" in code and not code.startswith(NOT_REPOSITORY) and not PLACEHOLDER.search(code):
            names.append(code)
    return names


def test_slug_follows_github():
    """GitHub's rule, on headings of these pages: code spans and colons dropped, spaces to '-'."""
    assert slug("On a cluster: `--executor dask`") == "on-a-cluster---executor-dask"
    assert slug("`update` and `render`: what each frame is charged") == \
        "update-and-render-what-each-frame-is-charged"
    assert slug("One scene differently: `per_scene:`") == "one-scene-differently-per_scene"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_links_point_at_files_and_anchors_that_exist(page):
    assert not broken_links(page), "\n".join(broken_links(page))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_named_repository_paths_exist(page):
    missing = [name for name in named_paths(page) if not (ROOT / name.rstrip("/")).exists()]
    assert not missing, f"{page.name} names paths that do not exist: {missing}"


def test_the_checks_see_the_pages_links_and_paths():
    """The checks look at something: the README links to every page of docs/, and the pages
    name dozens of repository paths (a regex that matched nothing would pass every page)."""
    readme_links = {t.partition("#")[0] for t in LINK.findall(prose((ROOT / "README.md").read_text()))}
    pages = {f"docs/{p.name}" for p in PAGES[1:]}
    assert pages <= readme_links, f"README links to no {sorted(pages - readme_links)}"
    assert sum(len(named_paths(p)) for p in PAGES) > 50


def test_the_run_counts_of_make_bench_are_what_it_plans():
    """Every "N runs" in the README, and docs/experiments.md's count of ``plan
    experiments/default.yaml``, is the number of runs make bench's experiment plans. Broken
    version caught (the old README): 554 runs in the text and 551 in the screenshot's
    caption."""
    from harness.run import plan_runs

    plan = plan_runs(experiment_path=str(ROOT / "experiments" / "default.yaml"),
                     scene_file=str(ROOT / "scenes.yaml"), scenes=None, techniques=None,
                     overrides={})
    readme = [int(n.replace(",", "")) for n in
              re.findall(r"\b(\d[\d,]*) runs\b", prose((ROOT / "README.md").read_text()))]
    experiments = re.findall(r"plan experiments/default.yaml` says (\d+) runs",
                             " ".join((ROOT / "docs" / "experiments.md").read_text().split()))
    assert readme and experiments, (readme, experiments)
    assert set(readme) | {int(n) for n in experiments} == {len(plan.runs)}

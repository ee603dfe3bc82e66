"""python -m papers ROOT: claims from ROOT/<experiment>/ into ROOT/papers.json, each
experiment's dashboard, and ROOT/papers.html; prints the Papers page's path."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from harness import report

from . import claims


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers", description=__doc__)
    parser.add_argument("root", help="directory holding one run directory per paper experiment")
    root = Path(parser.parse_args(argv).root)
    renderers = set()
    for name in claims.EXPERIMENTS:
        manifest = root / name / "manifest.json"
        if manifest.is_file():
            renderers.add(json.loads(manifest.read_text()).get("gl", {}).get("renderer", "?"))
    found = claims.evaluate(root)
    claims.write(root, found, renderer=", ".join(sorted(renderers)))
    for name in claims.EXPERIMENTS:
        if (root / name / "results.csv").is_file():
            report.build_report(root / name)
    page = report.build_papers_page(root)
    agree = sum(c.agrees for c in found)
    print(f"{agree} of {len(found)} claims agree; {page}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

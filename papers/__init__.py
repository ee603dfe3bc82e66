"""Paper reproductions: each founding paper's headline results next to what shadowbench measures.

``experiments/papers/*.yaml`` are run into ``ROOT/<experiment>/``; :func:`papers.claims.evaluate`
turns those results (and, for GMNPR Figures 5 and 6, the analytic formulas of
``techniques.warp_equations``) into claims written to ``ROOT/papers.json``, which
``harness.report.build_papers_page`` renders as ``ROOT/papers.html``.

One module per paper holds its claims (``pcf``, ``mdsm``, ``silhouette``, ``sv``, ``gmnpr``);
``common`` has the :class:`~papers.common.Claim` record, :class:`~papers.common.Runs` and the
helpers they share; ``claims`` maps each experiment to its claims and writes ``papers.json``.

    python -m papers ROOT      # claims, each experiment's dashboard, the Papers page
"""

"""The report: each experiment of the paper (``experiments/``, one module each, with its claims, tables and
figures) reads what its pipeline (``dvc.yaml`` at the root, or ``pipelines/<name>/``) left under ``data/`` and
becomes a :class:`~famarl_cli.report.section.Section`: our numbers beside the paper's claims, a three-way verdict
per claim (``verdicts``), tables (``results``) and figures (``plots``; PNG files). ``writer`` assembles report.md,
summary.json and the learning curves' CSV that the pipelines declare as DVC plots (``dvc plots show``,
``dvc plots diff``).
"""

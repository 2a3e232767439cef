"""Parameter studies at scale: many scenes x bodies x loads x positions, on Dask, resumable.

Not to be confused with :mod:`twoscale.paper`, which reruns the paper's own
numerical study (figs. 3-6). This package runs what a user's parameter study asks for
(``twoscale study STUDY.toml --out DIR``), one concept per module:

* :mod:`.spec`: the study file (TOML), validated like scenes (:mod:`.checks` shared with
  the rolling studies' reader);
* :mod:`.cases`: expansion into cases, and the scene each case solves (tips shifted by
  the position, only those under the body's footprint kept);
* :mod:`.keys`: a case's key, a hash of its inputs;
* :mod:`.solve`: one case solved, its result read by one adapter, failures recorded;
* :mod:`.providers`: bodies built once per process, the block's correction once per study;
* :mod:`.store`: per-case result folders written atomically (resume, Ctrl-C);
* :mod:`.execute`: running the unfinished cases, serially or on Dask (:mod:`.dask_backend`);
* :mod:`.tables`, :mod:`.figures`, :mod:`.outputs`: tidy tables (CSV, Parquet),
  summary.json and figures (the bar over cases is :class:`twoscale.progress.Progress`);
* rolling studies (a study file with a ``[rolling]`` table: road sections x bodies x
  materials x loads x speeds, each case a rolling run's files): :mod:`.rolling_spec` (the
  file), :mod:`.rolling_cases` (cases, keys, the scene each rolls), :mod:`.rolling_solve`
  (one roll and its cases' files), :mod:`.rolling_run` (resumable, serial or on Dask),
  :mod:`.rolling_tables` (``cases.csv``, ``bands.csv``, summary.json).

Dask (``distributed``) and ``pyarrow`` are the ``study`` extra; nothing here imports them
at import time.
"""

"""The file-to-file stages: the demos, the method's steps (segment, FAVAE pre-run and fit, traversal, a run's
evaluation) and the per-seed replicate that chains them (``famarl macros``). Each reads and writes artifacts; the CLI
parses options and calls them."""

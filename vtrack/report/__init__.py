"""The run report: one self-contained HTML page from the files of a `vtrack track` run."""

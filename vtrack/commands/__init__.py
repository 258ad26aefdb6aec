"""One module per command of INTERFACE.md.

Each module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``;
``vtrack.cli`` discovers them. Heavy imports belong inside ``run`` so ``--help`` stays fast.
"""

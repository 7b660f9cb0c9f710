"""Build tools, run in the source folder (``python -m tools.<name>``); not part of the installed program."""

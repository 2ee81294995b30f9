"""rotavat's version, written here only (pyproject.toml reads it: ``[tool.setuptools.dynamic]``).

A leaf: it imports nothing, so anything may stamp its outputs with it."""

__version__ = "0.1.0"

WRITTEN_BY = f"rotavat {__version__}"
"""How every file rotavat writes names its writer (``written_by:``, glTF ``generator``, the CLI's ``--version``)."""

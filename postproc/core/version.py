"""The version of postproc (one place: the package, the CLI's --version, the wheel and the verdicts say it)."""

__version__ = "0.1.0"

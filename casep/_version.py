"""The package version (its own module, so that subpackages need not import the package root)."""

__version__ = "0.2.0.dev0"

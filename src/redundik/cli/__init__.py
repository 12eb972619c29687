"""Command-line interface (``redundik ...``). Nothing in the library core imports this package."""

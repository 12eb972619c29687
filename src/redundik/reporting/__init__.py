"""Reporting of task runs: files (JSON, CSV), figures (matplotlib, lazily) and terminal tables."""

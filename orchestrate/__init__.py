"""Orchestration on top of the packages: the end-to-end demo, the benchmark tables, the training recipe.

The only package that may import `wildgen`, `unips` and `validate` together (see tests/test_layers.py).
"""
import scenes  # noqa: F401  (a clear error, not a traceback, outside the toolkit's environment)

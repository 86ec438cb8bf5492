"""Submissions: a single Python file with a manifest (``manifest``), flown in an isolated child
process (``sandbox`` on the parent's side, ``child`` inside) that speaks ``wire``'s format."""

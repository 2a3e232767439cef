"""Closed-form references (library code, tested on their own)."""

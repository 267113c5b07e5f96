"""The store: one SQLite file, written atomically, every row checksummed; its catalog,
keys, page packing, validation on open and size report.
"""

__all__ = ["catalog", "check", "database", "keys", "pagepack", "size"]

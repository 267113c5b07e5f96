"""The store: one SQLite file, written atomically, every row checksummed; its schema,
writer, reader, recovery of an interrupted edit, catalog, keys, page packing, validation
on open and size report.
"""

__all__ = ["catalog", "check", "keys", "pagepack", "reader", "recovery", "schema", "size",
           "writer"]

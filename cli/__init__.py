"""The `geoterrain` command line: Click commands, one module each, thin over the library."""

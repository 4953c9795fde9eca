"""Files: the HDF5 schema, its reader and writer, shards, and imported logs."""

"""Study 000: tool-tip force from two DIGIT tactile sensors (simulate, import, ingest, sync, split)."""

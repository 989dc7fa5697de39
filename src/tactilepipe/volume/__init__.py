"""Study 001: container volume from PapillArray forces (simulate, ingest, segment, fit, report)."""

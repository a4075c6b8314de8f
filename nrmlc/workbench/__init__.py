"""The workbench: run, score and compare trackers on OTB-style data (knows trackers only
through ``init`` / ``update``)."""

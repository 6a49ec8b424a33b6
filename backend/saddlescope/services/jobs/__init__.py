"""Jobs: created, queued, run stage by stage on a worker, fenced, and their failures in plain words."""

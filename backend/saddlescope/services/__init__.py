"""Use cases (run a job's stages, register rides, health): no FastAPI, no Celery here."""

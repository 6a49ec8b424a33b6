"""The database: models, their stored enumerations, the repositories that query them, sessions, migrations.

Import from the modules (``saddlescope.db.repositories``, ``saddlescope.db.enums``, ...); this package
imports none of them, so naming an enumeration does not load the models.
"""

__all__ = ["enums", "migrate", "models", "repositories", "session"]

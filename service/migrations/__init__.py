"""The database schema's history as Alembic revisions (``versions/``), applied by
:func:`service.migrate.upgrade_database` when the service starts."""

"""Alembic's environment: run on the connection :func:`service.migrate.upgrade_database`
hands over (``config.attributes["connection"]``), against the ORM's metadata."""

from __future__ import annotations

from alembic import context

from service.storage import metadata

connection = context.config.attributes["connection"]
context.configure(
    connection=connection,
    target_metadata=metadata,
    # SQLite cannot ALTER most columns: batch mode copies the table instead.
    render_as_batch=connection.dialect.name == "sqlite",
)
with context.begin_transaction():
    context.run_migrations()

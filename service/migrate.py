"""Schema migrations with Alembic: a stored database survives an upgrade of the service.

:func:`upgrade_database` brings any database the service may meet to the newest revision
in ``service/migrations/versions``: an empty one, one at an older revision, and one made
before migrations existed (the service created its tables itself up to revision 0001: such a
database has the tables but no ``alembic_version``, and is stamped 0001 first). The service
runs it once at start, before any worker opens the database.
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import inspect
from sqlalchemy.engine import Connection, Engine

MIGRATIONS = Path(__file__).with_name("migrations")
#: The revision whose schema the service created without Alembic (before migrations).
BASELINE = "0001"


def _config(connection: Connection) -> Config:
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.attributes["connection"] = connection
    return config


def head_revision() -> str:
    """The newest revision the code knows."""
    head = ScriptDirectory(str(MIGRATIONS)).get_current_head()
    assert head is not None, "service/migrations/versions holds no revision"
    return head


def current_revision(engine: Engine) -> str | None:
    """The database's revision (None: none recorded)."""
    with engine.connect() as connection:
        return MigrationContext.configure(connection).get_current_revision()


def upgrade_database(engine: Engine) -> str:
    """Upgrade the database to the head revision (module docstring); returns it."""
    with engine.begin() as connection:
        config = _config(connection)
        tables = set(inspect(connection).get_table_names())
        if "tasks" in tables and "alembic_version" not in tables:
            command.stamp(config, BASELINE)
        command.upgrade(config, "head")
    return head_revision()

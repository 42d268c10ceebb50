"""Alembic's environment for the history store: migrations run on the connection ``history.store``
hands over (``config.attributes["connection"]``), inside its transaction (which holds the store's
lock), never from an alembic.ini."""

from alembic import context

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=None, render_as_batch=True)
with context.begin_transaction():
    context.run_migrations()

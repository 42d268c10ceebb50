"""The rulebook's readings setting (notice|error) as a column of its own, and the indexes the history
queries filter on (when, unit, firmware, check name).

Revision ID: 0002
Revises: 0001
"""

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("runs", sa.Column("readings", sa.String(20)))
    op.create_index("ix_runs_started", "runs", ["started"])
    op.create_index("ix_runs_unit", "runs", ["unit"])
    op.create_index("ix_runs_firmware", "runs", ["firmware"])
    op.create_index("ix_checks_name", "checks", ["name"])


def downgrade() -> None:
    for name, table in (("ix_checks_name", "checks"), ("ix_runs_firmware", "runs"), ("ix_runs_unit", "runs"),
                        ("ix_runs_started", "runs")):
        op.drop_index(name, table_name=table)
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("readings")

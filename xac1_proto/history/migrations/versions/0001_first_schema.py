"""The first schema: runs, their checks, settings and files.

Revision ID: 0001
Revises:
"""

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "runs",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("uid", sa.String(32), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("started", sa.DateTime(timezone=True), nullable=False),
        sa.Column("ended", sa.DateTime(timezone=True), nullable=False),
        sa.Column("station", sa.String(200)),
        sa.Column("operator", sa.String(200)),
        sa.Column("port", sa.String(500)),
        sa.Column("unit", sa.String(200)),
        sa.Column("firmware", sa.String(100)),
        sa.Column("verdict", sa.String(60), nullable=False),
        sa.Column("verdict_line", sa.Text, nullable=False),
        sa.Column("exit_status", sa.Integer, nullable=False),
        sa.Column("interrupted", sa.String(20)),
        sa.Column("kit_version", sa.String(40), nullable=False),
        sa.Column("fleet", sa.String(32)),
        sa.Column("command_line", sa.Text, nullable=False),
        sa.UniqueConstraint("uid", name="uq_runs_uid"),
    )
    op.create_table(
        "checks",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
        sa.Column("position", sa.Integer, nullable=False),
        sa.Column("name", sa.String(300), nullable=False),
        sa.Column("outcome", sa.String(20), nullable=False),
        sa.Column("rule", sa.Text, nullable=False),
        sa.Column("topic", sa.String(100), nullable=False),
        sa.Column("codes", sa.Text, nullable=False),
        sa.Column("message", sa.Text, nullable=False),
        sa.Column("info", sa.Boolean, nullable=False),
    )
    op.create_index("ix_checks_run_id", "checks", ["run_id"])
    op.create_table(
        "settings",
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("name", sa.String(100), primary_key=True),
        sa.Column("value", sa.Text, nullable=False),
    )
    op.create_table(
        "files",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
        sa.Column("what", sa.String(40), nullable=False),
        sa.Column("path", sa.Text, nullable=False),
    )
    op.create_index("ix_files_run_id", "files", ["run_id"])


def downgrade() -> None:
    for table in ("files", "settings", "checks", "runs"):
        op.drop_table(table)

"""size charts: ready-to-wear charts a clinic or a manufacturer registers

Each row is one validated chart (app.geometry.garment.size_charts) of a tenant, its
JSON form in ``body``.  The shipped example is not stored: it is read from the package.

Revision ID: 0009
Revises: 0008
Create Date: 2026-12-02
"""
import sqlalchemy as sa
from alembic import op

revision = "0009"
down_revision = "0008"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "size_charts",
        sa.Column("id", sa.String(32), primary_key=True),
        sa.Column("tenant_id", sa.String(32), sa.ForeignKey("tenants.id", ondelete="RESTRICT"), nullable=False),
        sa.Column("product", sa.String(100), nullable=False),
        sa.Column("stocking_type", sa.String(2), nullable=False),
        sa.Column("body", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    )
    op.create_index("ix_size_charts_tenant", "size_charts", ["tenant_id"])


def downgrade() -> None:
    op.drop_index("ix_size_charts_tenant", "size_charts")
    op.drop_table("size_charts")

"""job leases: a running job belongs to one runner until its lease expires

A runner that claims a job holds it for CALF_JOB_LEASE_S and renews the lease while the
fit runs; only a job whose lease has expired (its runner died) is taken by another.
Jobs left running by a runner before this revision have no lease, which counts as
expired: the next runner takes them.

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-22
"""
import sqlalchemy as sa
from alembic import op

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("lease_owner", sa.String(100)))
        batch.add_column(sa.Column("lease_expires_at", sa.DateTime(timezone=True)))


def downgrade() -> None:
    with op.batch_alter_table("jobs") as batch:
        batch.drop_column("lease_expires_at")
        batch.drop_column("lease_owner")

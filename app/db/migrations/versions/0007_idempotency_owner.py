"""idempotency reservations name their owner process

A pending Idempotency-Key reservation records the API process answering it
(``host:pid:tag``, as job leases do): a retry after that process died finds the
reservation's owner gone and takes it over at once, instead of answering 409 for the
15 minutes a reservation used to be held.  Rows from before this revision have no
owner and are taken over after the fixed hold as before.

Revision ID: 0007
Revises: 0006
Create Date: 2026-12-01
"""
import sqlalchemy as sa
from alembic import op

revision = "0007"
down_revision = "0006"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("idempotent_requests") as batch:
        batch.add_column(sa.Column("owner", sa.String(100)))


def downgrade() -> None:
    with op.batch_alter_table("idempotent_requests") as batch:
        batch.drop_column("owner")

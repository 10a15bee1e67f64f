"""case references: jobs and records carry the clinic's pseudonymous case reference

A clinic sends its own patient or case id (pseudonymous: never a name or a birth date;
validated by app.services.cases) with an upload; the job keeps it and the record made
from the job inherits it, so the records of one case can be listed and one case's data
erased.  Rows from before this revision have none.

Revision ID: 0008
Revises: 0007
Create Date: 2026-12-02
"""
import sqlalchemy as sa
from alembic import op

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("case_ref", sa.String(64)))
    with op.batch_alter_table("records") as batch:
        batch.add_column(sa.Column("case_ref", sa.String(64)))
    op.create_index("ix_records_tenant_case", "records", ["tenant_id", "case_ref"])
    op.create_index("ix_jobs_tenant_case", "jobs", ["tenant_id", "case_ref"])


def downgrade() -> None:
    op.drop_index("ix_jobs_tenant_case", "jobs")
    op.drop_index("ix_records_tenant_case", "records")
    with op.batch_alter_table("records") as batch:
        batch.drop_column("case_ref")
    with op.batch_alter_table("jobs") as batch:
        batch.drop_column("case_ref")

"""tenants and API keys; every scan, job, record and design belongs to a tenant

Data stored before tenants existed moves to the tenant "default" (which an
unauthenticated local service acts as); `calf-nurbs keys create --tenant default`
gives that clinic a key.  Scans become unique per tenant, not globally: the same bytes
uploaded by two clinics are two rows (the file on disk is shared).

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-22
"""
from datetime import UTC, datetime

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None

DEFAULT = "default"
OWNED = ("scans", "jobs", "records", "designs")


def upgrade() -> None:
    tenants = op.create_table(
        "tenants",
        sa.Column("id", sa.String(32), primary_key=True),
        sa.Column("name", sa.String(100), nullable=False, unique=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    )
    op.bulk_insert(tenants, [{"id": DEFAULT, "name": DEFAULT, "created_at": datetime.now(UTC)}])
    op.create_table(
        "api_keys",
        sa.Column("id", sa.String(32), primary_key=True),
        sa.Column("tenant_id", sa.String(32), sa.ForeignKey("tenants.id", ondelete="CASCADE"), nullable=False),
        sa.Column("prefix", sa.String(32), nullable=False, unique=True),
        sa.Column("secret_sha256", sa.String(64), nullable=False),
        sa.Column("scopes", sa.String(100), nullable=False),
        sa.Column("label", sa.String(100)),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("expires_at", sa.DateTime(timezone=True)),
        sa.Column("revoked_at", sa.DateTime(timezone=True)),
        sa.Column("last_used_at", sa.DateTime(timezone=True)),
    )
    op.create_index("ix_api_keys_tenant", "api_keys", ["tenant_id"])
    postgres = op.get_bind().dialect.name == "postgresql"
    # SQLite's UNIQUE(sha256) of 0001 has no name: batch mode names it by this convention
    convention = {"uq": "uq_%(table_name)s_%(column_0_name)s"}
    for table in OWNED:
        with op.batch_alter_table(table, naming_convention=convention) as batch:
            batch.add_column(sa.Column("tenant_id", sa.String(32), nullable=False, server_default=DEFAULT))
            batch.create_foreign_key(f"fk_{table}_tenant", "tenants", ["tenant_id"], ["id"], ondelete="RESTRICT")
            if table == "scans":
                batch.drop_constraint("scans_sha256_key" if postgres else "uq_scans_sha256", type_="unique")
                batch.create_unique_constraint("uq_scans_tenant_sha256", ["tenant_id", "sha256"])
    op.drop_index("ix_records_created", table_name="records")
    op.create_index("ix_records_tenant_created", "records", ["tenant_id", "created_at"])
    op.create_index("ix_jobs_tenant", "jobs", ["tenant_id"])
    op.create_index("ix_designs_tenant", "designs", ["tenant_id"])


def downgrade() -> None:
    op.drop_index("ix_designs_tenant", table_name="designs")
    op.drop_index("ix_jobs_tenant", table_name="jobs")
    op.drop_index("ix_records_tenant_created", table_name="records")
    op.create_index("ix_records_created", "records", ["created_at"])
    for table in OWNED:
        with op.batch_alter_table(table) as batch:
            if table == "scans":
                batch.drop_constraint("uq_scans_tenant_sha256", type_="unique")
                batch.create_unique_constraint("uq_scans_sha256", ["sha256"])
            batch.drop_constraint(f"fk_{table}_tenant", type_="foreignkey")
            batch.drop_column("tenant_id")
    op.drop_index("ix_api_keys_tenant", table_name="api_keys")
    op.drop_table("api_keys")
    op.drop_table("tenants")

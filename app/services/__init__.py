"""Service layer: orchestrates uploads, fitting jobs, records and designs."""

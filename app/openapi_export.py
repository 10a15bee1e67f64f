"""Write openapi/openapi.json from the application (``make openapi``)."""

from __future__ import annotations

import json
from pathlib import Path

from app.main import app

TARGET = Path(__file__).resolve().parents[1] / "openapi" / "openapi.json"


def render() -> str:
    return json.dumps(app.openapi(), indent=2, sort_keys=True) + "\n"


if __name__ == "__main__":
    TARGET.write_text(render())
    print(f"wrote {TARGET}")

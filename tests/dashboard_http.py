"""HTTP calls to a dashboard under test, as its own page makes them (shared by the dashboard
tests; the dashboard refuses a POST without the page's custom header: its CSRF check)."""

from __future__ import annotations

import json
import urllib.error
import urllib.request
from typing import Any

from tests.conftest import SOON_S


def post_json(url: str, body: bytes) -> tuple[int, Any]:
    """POST ``body`` (JSON) with the page's headers; (status, decoded JSON reply)."""
    req = urllib.request.Request(url, body, {"Content-Type": "application/json", "X-Dexaug": "1"})
    try:
        with urllib.request.urlopen(req, timeout=SOON_S) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())

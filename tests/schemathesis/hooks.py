"""Schemathesis hooks for `api/openapi.yaml` (loaded through SCHEMATHESIS_HOOKS by tests/schemathesis.rs).

1. The mesh media types carry raw bytes, like application/octet-stream.
2. Two rules of POST /v1/jobs span two locations of the request, which JSON Schema cannot
   express; the spec states them in prose and the server answers 400 `bad-request`:
   - a query `params` together with a multipart `params` part;
   - a query `stages` together with `stages` inside the parameters (query or part).
   Schema-valid (positive) cases that break one of them are not generated as positive
   data; tests/api checks the 400 itself.
3. A negative case whose file was mutated to a non-string is dropped: it goes out as valid bytes.
"""

import json

import schemathesis
from schemathesis.core import NOT_SET

for media_type in ("model/stl", "model/obj", "model/ply", "application/x-gmsh"):
    schemathesis.serializer.alias(media_type, "application/octet-stream")


def _as_object(value):
    """The parameters as a dict (the query `params` arrives JSON-encoded)."""
    if isinstance(value, (str, bytes)):
        try:
            value = json.loads(value)
        except ValueError:
            return None
    return value if isinstance(value, dict) else None


def _breaks_a_cross_location_rule(case) -> bool:
    query = case.query or {}
    body = case.body if isinstance(case.body, dict) else {}
    part = body.get("params") if case.media_type == "multipart/form-data" else None
    if part is not None and "params" in query:
        return True
    if "stages" in query:
        for given in (query.get("params"), part):
            params = _as_object(given)
            if params is not None and "stages" in params:
                return True
    return False


def _is_bytes(value) -> bool:
    """True for what can travel as a file: text or bytes (schemathesis wraps bytes in `Binary`)."""
    return isinstance(value, (str, bytes)) or type(value).__name__ == "Binary"


def _file_mutated_to_non_bytes(case) -> bool:
    """A negative case whose file (raw body or `file` part) became a number, boolean, array or
    object or null: on the wire it is still just bytes (`true`, `None`), a valid non-empty file, so the
    request it sends does not violate the schema."""
    if case.media_type == "multipart/form-data":
        body = case.body if isinstance(case.body, dict) else {}
        return "file" in body and not _is_bytes(body["file"])
    return case.body is not NOT_SET and not _is_bytes(case.body)


@schemathesis.hook
def filter_case(context, case):
    meta = case.meta
    if meta is not None and not meta.generation.mode.is_positive:
        return not _file_mutated_to_non_bytes(case)
    return not _breaks_a_cross_location_rule(case)

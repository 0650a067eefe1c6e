"""Declared file formats: the shared base of every user file's model (pydantic v2), its JSON Schema,
and the one translation of a validation error into the one-line :class:`UserError`.

Each package declares the formats it owns as :class:`FileModel` subclasses (scenario YAML in
``planfile``, vehicle and model files in ``physics``, the manifest in ``identify``, ...); field names
carry the unit (``start`` in m where the name cannot, then the description says it). Loaders call
:func:`validate` once on the parsed document; a mistake becomes ``FILE: key.path: what; expected FORM``:

* the key path is the error's location (``vehicles.shuttle.start``, ``obstacles[2].max``);
* the expected form is read from the model's own JSON Schema (:func:`expected_form`), so the message
  and the schema an editor shows agree: ``a number in (0, 1]``, ``one of conservative, model, forbid``,
  ``a list of 3 finite numbers [x, y, z]``;
* an unknown key names the closest known key (difflib) and the keys allowed there.

A model's own checks raise :func:`problem` (a message, optionally at a key below the model's) or
:func:`missing` (a key that is required in this case); both come out in the same one-line form.
"""

from __future__ import annotations

import copy
import difflib
from collections.abc import Mapping
from functools import cache
from typing import Annotated, Any, TypeVar

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, Strict, TypeAdapter, ValidationError
from pydantic.json_schema import GenerateJsonSchema
from pydantic_core import PydanticCustomError

from proxplan.fileio.errors import UserError

JSON_SCHEMA_DIALECT = "http://json-schema.org/draft-07/schema#"
"""The schemas are written for draft 7: what yaml-language-server (VS Code's YAML extension and other
LSP editors) validates with today; pydantic's 2020-12 ``prefixItems`` become draft-7 ``items``."""


class FileModel(BaseModel):
    """Base of every declared file section: unknown keys are errors, values are not converted
    (``"1.5"`` is not a number, ``1`` is not ``true``), instances are frozen. Validators are built on
    first use (``defer_build``), so importing a package stays cheap."""

    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True, strict=False)


def _as_name(value: Any) -> Any:
    """A mapping key written as a number in YAML (``1:``) is a name like any other."""
    return str(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else value


Number = Annotated[float, Strict(), Field(allow_inf_nan=False)]
"""A finite number (an integer is accepted; text, true/false, NaN and infinity are not)."""
Whole = Annotated[int, Strict()]
"""A whole number (not 1.0, not true)."""
Flag = Annotated[bool, Strict()]
"""true or false (not 1, not "yes" in quotes)."""
Text = Annotated[str, Strict()]
"""Text (a number is not text)."""
Name = Annotated[str, BeforeValidator(_as_name)]
"""A name used as a mapping key (a YAML key that reads as a number is taken as its text)."""
Positive = Annotated[Number, Field(gt=0)]
"""A finite number > 0."""
NonNegative = Annotated[Number, Field(ge=0)]
"""A finite number >= 0."""
Vec3 = tuple[Number, Number, Number]
"""Three finite numbers [x, y, z]."""


def optional(description: str, **kwargs: Any) -> Any:
    """An optional key: absent (None on the model) means the loader's default, which ``description``
    states; an explicit ``null`` is an error unless the key's type allows None."""
    return Field(None, description=description, **kwargs)


def problem(message: str, *, at: str | tuple = ()) -> PydanticCustomError:
    """An error a model's validator raises: ``message`` is the text after the key path; ``at`` a key
    path below the validated model's that the message is about: dotted (``"params.gain"``) or, where a
    key may hold a dot (a vehicle name), a tuple (``("vehicles", name, "t_s")``)."""
    return PydanticCustomError("proxplan", "{message}", {"message": message, "at": _parts(at)})


def missing(key: str | tuple) -> PydanticCustomError:
    """A key the model requires in this case (e.g. a vehicle without ``base``): reported like a
    missing required key, with the key's expected form."""
    return PydanticCustomError("missing", "Field required", {"at": _parts(key)})


def _parts(at: str | tuple) -> tuple:
    return tuple(at.split(".")) if isinstance(at, str) and at else tuple(at)


M = TypeVar("M")


def validate(model: type[M] | TypeAdapter, doc: Any, *, label: str, at: tuple = ()) -> M:
    """``doc`` validated by ``model`` (a :class:`FileModel` subclass or a :class:`TypeAdapter`);
    :class:`UserError` ``"LABEL: key.path: ...; expected FORM"`` on the first mistake otherwise.
    ``at`` is where ``doc`` sits in its file (``("vehicles", "heavy")``): the key paths start there."""
    try:
        if isinstance(model, TypeAdapter):
            return model.validate_python(doc)
        return model.model_validate(doc)  # type: ignore[attr-defined]
    except ValidationError as err:
        raise UserError(error_line(err, _schema_of(model), doc, label, at=at)) from None  # type: ignore[arg-type]


def json_schema(model: type[BaseModel] | TypeAdapter, *, title: str, description: str) -> dict:
    """The JSON Schema (draft 7) of ``model`` for editors: field descriptions (with units),
    defaults, bounds and allowed values; no generated titles."""
    body = copy.deepcopy(_schema_of(model))
    head = {"$schema": JSON_SCHEMA_DIALECT, "title": title, "description": description}
    _for_editors(head)
    body.pop("title", None)
    body.pop("description", None)
    return head | body


class _Generator(GenerateJsonSchema):
    """pydantic's generator without the titles it derives from field and class names (editors show
    them as noise next to the descriptions)."""

    def field_title_should_be_set(self, schema: Any) -> bool:
        return False

    def generate(self, schema: Any, mode: Any = "validation") -> dict:
        out = super().generate(schema, mode)
        for definition in out.get("$defs", {}).values():
            definition.pop("title", None)
        _for_editors(out)
        return out


def _for_editors(node: Any) -> None:
    """Tidy a generated schema in place for editors (draft 7):

    * ``"default": null`` on a key that cannot be null only means "absent" (the loader fills in the
      real default, which the description states): removed;
    * a list of one kind of fixed length (``prefixItems`` of equal entries) becomes draft-7 ``items``;
    * descriptions: one line each, reStructuredText ````code```` as Markdown ```code```.
    """
    if isinstance(node, dict):
        nullable = node.get("type") == "null" or any(b.get("type") == "null" for b in node.get("anyOf", []))
        if "default" in node and node["default"] is None and not nullable:
            del node["default"]
        prefix = node.get("prefixItems")
        if prefix and all(p == prefix[0] for p in prefix) and "items" not in node:
            node["items"] = node.pop("prefixItems")[0]
        if isinstance(node.get("description"), str):
            node["description"] = " ".join(node["description"].replace("``", "`").split())
        for value in node.values():
            _for_editors(value)
    elif isinstance(node, list):
        for value in node:
            _for_editors(value)


@cache
def _schema_of(model: Any) -> dict:
    """The JSON Schema error messages read expected forms from (built once per model, on the first mistake)."""
    if isinstance(model, TypeAdapter):
        return model.json_schema(schema_generator=_Generator)
    return model.model_json_schema(schema_generator=_Generator)


# ------------------------------------------------------------------------------------ error lines


def error_line(err: ValidationError, schema: dict, doc: Any, label: str, *, at: tuple = ()) -> str:
    """The one-line message of the first mistake in ``err`` (unknown keys first: a misspelt key also
    leaves the intended one missing, and the misspelling is what the user has to fix)."""
    errors = err.errors(include_url=False)
    first = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    ctx = first.get("ctx") or {}
    loc = _keys_as_names(schema, [p for p in first["loc"] if p != "[key]"] + list(ctx.get("at") or ()))
    kind = first["type"]
    if kind == "extra_forbidden":
        allowed = list(resolve_node(_node_at(schema, loc[:-1]), schema).get("properties", {}))
        return f"{_where(label, [*at, *loc])}: unknown key{_did_you_mean(str(loc[-1]), allowed)}; expected one of: {', '.join(allowed)}"
    if kind == "proxplan":
        return f"{_where(label, [*at, *loc])}: {ctx['message']}"
    whole = _whole_vector(schema, loc)
    if whole != loc:  # a missing or bad coordinate: the list as a whole is wrong
        loc, kind = whole, "vector"
    form = "a finite number" if kind == "finite_number" else expected_form(_node_at(schema, loc), schema)
    if kind == "missing":
        about = _node_at(schema, loc).get("description")
        return f"{_where(label, [*at, *loc])}: missing; expected {form}" + (f" ({about})" if about else "")
    if (
        kind in ("too_long", "too_short")
        and isinstance(ctx.get("actual_length"), int)
        and _is_mapping_or_list(schema, loc)
    ):
        return f"{_where(label, [*at, *loc])}: expected {form}, got {ctx['actual_length']} entries"
    return f"{_where(label, [*at, *loc])}: expected {form}, got {_show(_value_at(doc, loc))}"


def _keys_as_names(schema: dict, loc: list) -> list:
    """``loc`` with list indices as ints and mapping keys as text (a YAML key ``1:`` is a name; an
    ``at`` path from :func:`problem` arrives as text)."""
    out: list = []
    for part in loc:
        is_list = _node_at(schema, out).get("type") == "array"
        out.append(int(part) if is_list and str(part).isdigit() else str(part))
    return out


def _where(label: str, loc: list) -> str:
    path = key_path(loc)
    if not path:
        return label
    return f"{label}{path}" if path.startswith("[") else f"{label}: {path}"


def key_path(loc: list | tuple) -> str:
    """``("vehicles", "a", "start")`` -> ``vehicles.a.start``; list indices as ``[i]``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _did_you_mean(key: str, allowed: list[str]) -> str:
    close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
    if not close:  # a key written without its unit suffix (speed -> max_speed_mps)
        close = [a for a in allowed if key and key.lower() in a.lower()][:1]
    return f" (did you mean {close[0]!r}?)" if close else ""


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _value_at(doc: Any, loc: list) -> Any:
    for part in loc:
        if isinstance(doc, Mapping) and part in doc:
            doc = doc[part]
        elif isinstance(doc, Mapping) and str(part) in {str(k) for k in doc}:
            doc = next(v for k, v in doc.items() if str(k) == str(part))
        elif isinstance(doc, (list, tuple)) and isinstance(part, int) and part < len(doc):
            doc = doc[part]
        else:
            return None
    return doc


# ------------------------------------------------------------------------- schema walking and forms


def resolve_node(node: dict, root: dict) -> dict:
    """``node`` (of schema ``root``) with ``$ref`` followed and an optional (``X or null``) reduced to ``X``."""
    while True:
        if "$ref" in node:
            node = {**root["$defs"][node["$ref"].split("/")[-1]], **{k: v for k, v in node.items() if k != "$ref"}}
            continue
        branches = [b for b in node.get("anyOf", []) if b.get("type") != "null"]
        if len(branches) == 1 and len(node["anyOf"]) == 2:
            node = {**{k: v for k, v in node.items() if k != "anyOf"}, **branches[0]}
            continue
        return node


def _child(node: dict, part: Any, root: dict) -> dict:
    node = resolve_node(node, root)
    if isinstance(part, int):
        return node.get("items", {})
    props = node.get("properties", {})
    if part in props:
        return props[part]
    extra = node.get("additionalProperties")
    return extra if isinstance(extra, dict) else {}


def _node_at(schema: dict, loc: list) -> dict:
    node = schema
    for part in loc:
        node = _child(node, part, schema)
    return resolve_node(node, schema)


def _whole_vector(schema: dict, loc: list) -> list:
    """A mistake inside a fixed-length list ([x, y, z]) is reported on the whole list."""
    if loc and isinstance(loc[-1], int) and _fixed_length(_node_at(schema, loc[:-1])):
        return loc[:-1]
    return loc


def _fixed_length(node: dict) -> int | None:
    """The length of a fixed-length list node (``[x, y, z]``), None for others."""
    n = node.get("minItems")
    return n if node.get("type") == "array" and n is not None and node.get("maxItems") == n else None


def _is_mapping_or_list(schema: dict, loc: list) -> bool:
    return _node_at(schema, loc).get("type") in ("object", "array")


def _number_form(node: dict, noun: str) -> str:
    lo = node.get("minimum", node.get("exclusiveMinimum"))
    hi = node.get("maximum", node.get("exclusiveMaximum"))
    if lo is not None and hi is not None:
        left = "[" if "minimum" in node else "("
        right = "]" if "maximum" in node else ")"
        return f"{noun} in {left}{lo:g}, {hi:g}{right}"
    if node.get("exclusiveMinimum") == 0 and hi is None:
        return f"a positive {noun.removeprefix('a ')}"
    if lo is not None:
        return f"{noun} {'>=' if 'minimum' in node else '>'} {lo:g}"
    if hi is not None:
        return f"{noun} {'<=' if 'maximum' in node else '<'} {hi:g}"
    return noun


def expected_form(node: dict, root: dict) -> str:
    """A short description of what ``node`` (a JSON Schema node of ``root``) accepts."""
    node = resolve_node(node, root)
    if "enum" in node:
        return "one of " + ", ".join(str(v) for v in node["enum"])
    if "const" in node:
        return str(node["const"]).lower() if isinstance(node["const"], bool) else str(node["const"])
    kind = node.get("type")
    for key in ("oneOf", "anyOf"):
        if key in node and kind is None:
            forms = [expected_form(b, root) for b in node[key] if b.get("type") != "null"]
            return " or ".join(dict.fromkeys(forms))
    if kind == "number":
        return _number_form(
            node,
            "a finite number"
            if not any(k in node for k in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum"))
            else "a number",
        )
    if kind == "integer":
        return _number_form(node, "a whole number")
    if kind == "boolean":
        return "true or false"
    if kind == "string":
        return "non-empty text" if node.get("minLength") else "text"
    if kind == "array":
        n = _fixed_length(node)
        items = node.get("items")
        if n and items and resolve_node(items, root).get("type") == "number":
            return f"a list of {n} finite numbers" + (" [x, y, z]" if n == 3 else "")
        return f"a list of {_plural(expected_form(items, root))}" if items else "a list"
    if kind == "object":
        props = node.get("properties")
        if props:
            return "a mapping with keys " + ", ".join(props)
        extra = node.get("additionalProperties")
        if isinstance(extra, dict) and extra:
            inner = expected_form(extra, root)
            if inner.startswith("a mapping with keys "):
                inner = "{" + inner.removeprefix("a mapping with keys ") + "}"
            return f"a mapping NAME: {inner.removeprefix('a ')}"
        return "a mapping"
    return "a value"


def _plural(form: str) -> str:
    """The form of one entry as the entries of a list or mapping ("a list of ...")."""
    if form.startswith("a mapping with keys "):
        return "{" + form.removeprefix("a mapping with keys ") + "}"
    if form.startswith("a list of 3 finite numbers [x, y, z]"):
        return "[x, y, z] rows"
    return {"a finite number": "finite numbers", "text": "texts", "non-empty text": "non-empty texts"}.get(form, form)


def schema_rows(schema: dict) -> list[tuple[str, str, str]]:
    """(key path, expected form, description) of every key of ``schema``, in declaration order;
    ``NAME`` stands for a name the user chooses, ``[i]`` for a list entry."""
    rows: list[tuple[str, str, str]] = []

    def walk(node: dict, path: str) -> None:
        node = resolve_node(node, schema)
        for key, child in node.get("properties", {}).items():
            sub = f"{path}.{key}" if path else key
            rows.append((sub, expected_form(child, schema), resolve_node(child, schema).get("description", "")))
            walk(child, sub)
        for part, inner in (("NAME", node.get("additionalProperties")), ("[i]", node.get("items"))):
            if isinstance(inner, dict) and resolve_node(inner, schema).get("properties"):
                walk(inner, f"{path}.{part}" if part == "NAME" else f"{path}{part}")

    walk(schema, "")
    return rows

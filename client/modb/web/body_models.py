"""What each write's JSON body may hold, declared once as a pydantic model in strict mode: numbers
are numbers (never booleans or strings), booleans booleans, lists lists of the right items, objects
only the fields they know. /api/openapi.json publishes these models' JSON Schema (openapi.py), and a
refusal names the field and what it takes in the words of that schema's descriptions (bodies.py).

Every constraint is one a JSON Schema states. Most are pydantic's own (type, range, length,
pattern, required, additionalProperties); the few beyond its vocabulary are stated as schema
keywords here and checked from those same keywords: `not` (a direction of three zeros, a null
document), a model's `minProperties` (a change that changes nothing) and its `oneOf` of required
fields (the clips named by ids or by a collection, not both). Edit scripts are the kernel's own
(modb_kernel/edits.py): checked by its script_errors, as the database's trigger checks them, and
published from its table of commands."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    WithJsonSchema,
    create_model,
    model_validator,
)
from pydantic.fields import FieldInfo
from pydantic.json_schema import GenerateJsonSchema
from pydantic_core import PydanticCustomError

from modb.validation import number_range
from modb_kernel.edits import _PARAMETERS as KERNEL_COMMANDS
from modb_kernel import pose_edits
from modb_kernel.edits import FPS_RANGE, script_errors

MAX_ID = 2**63 - 1  # a bigint
MAX_IDS = 10_000  # ids in one request
MAX_NAME = 200  # characters of a name or path

# Patterns (ECMA 262 as JSON Schema has them; pydantic checks them with Rust's regex, which reads
# these alike): no control characters, not blank; a name is not '.' or '..' and holds no '/'.
_CONTROL = r"\x00-\x1f\x7f"
_LINE_CONTROL = r"\x00-\x08\x0b-\x1f\x7f"  # a comment may hold tabs and newlines
_SPACE = rf"[^\S{_CONTROL}]"
_SEGMENT = (
    rf"(?:[^/{_CONTROL}]*[^/\s{_CONTROL}.][^/{_CONTROL}]*"  # something besides dots and spaces
    rf"|{_SPACE}*\.(?:\.|{_SPACE})+\.{_SPACE}*)"  # or dots and spaces, but not '.' or '..'
)
LINE = rf"^[^{_CONTROL}]*[^\s{_CONTROL}][^{_CONTROL}]*$"
LINES = rf"^[^{_LINE_CONTROL}]*[^\s{_CONTROL}][^{_LINE_CONTROL}]*$"
NAME_PATTERN = rf"^{_SEGMENT}$"
PATH_PATTERN = rf"^{_SEGMENT}(?:/{_SEGMENT})*$"
PARENT_PATTERN = rf"^(?:{_SEGMENT}(?:/{_SEGMENT})*)?$"


def about(kind: Any) -> str:
    """The description a type was declared with ('anything' when none)."""
    for meta in reversed(getattr(kind, "__metadata__", ())):
        if isinstance(meta, FieldInfo) and meta.description:
            return meta.description
    doc = getattr(kind, "__doc__", None) if isinstance(kind, type) else None
    return doc.split("\n\n")[0] if doc and issubclass(kind, BaseModel) else "anything"


# --- `not`: a value a type refuses, stated once as the schema it must not match -------------------

_JSON_TYPES = {"null": type(None), "boolean": bool, "object": dict, "array": list, "string": str}


def _matches(schema: dict[str, Any], value: Any) -> bool:
    """`value` against the few keywords a `not` here uses: type, const, items."""
    for key, wanted in schema.items():
        if key == "type" and not isinstance(value, _JSON_TYPES[wanted]):
            return False
        same_kind = isinstance(value, bool) == isinstance(wanted, bool)  # (False == 0 in Python)
        if key == "const" and not (same_kind and value == wanted):
            return False
        if key == "items" and not (
            isinstance(value, list) and all(_matches(wanted, v) for v in value)
        ):
            return False
    return True


def refusing(schema: dict[str, Any]) -> tuple[Any, ...]:
    """Annotations: the schema says `not: schema`, and a value matching it is refused."""

    def check(value: Any) -> Any:
        if _matches(schema, value):
            raise PydanticCustomError("not", "matches what it must not be")
        return value

    return Field(json_schema_extra={"not": schema}), AfterValidator(check)


# --- the kinds of field ---------------------------------------------------------------------------


def whole(what: str = "an id", least: int = 1, most: int = MAX_ID) -> Any:
    words = f"{what} (a whole number from {least} to {most})"
    return Annotated[int, Field(ge=least, le=most, description=words)]


def number(least: float, most: float, unit: str = "") -> Any:
    span = number_range(least, most, unit=unit)
    return Annotated[float, Field(ge=least, le=most, allow_inf_nan=False, description=span)]


FLAG = Annotated[bool, Field(description="true or false")]
FPS = number(*FPS_RANGE, unit="fps")


def text(most: int = MAX_NAME, lines: bool = False) -> Any:
    span = f"a string of 1 to {most} characters" + ("" if lines else " on one line")
    return Annotated[str, Field(min_length=1, max_length=most, pattern=LINES if lines else LINE,
                                description=span)]  # fmt: skip


TEXT = text()
NAME = Annotated[str, Field(min_length=1, max_length=MAX_NAME, pattern=NAME_PATTERN,
                            description=f"a name of 1 to {MAX_NAME} characters without '/' "
                            "(and not '.' or '..')")]  # fmt: skip
PATH = Annotated[str, Field(min_length=1, max_length=MAX_NAME, pattern=PATH_PATTERN,
                            description="a collection path such as 'bandai/walks' (names joined "
                            f"by '/'), of 1 to {MAX_NAME} characters")]  # fmt: skip
PARENT = Annotated[str, Field(max_length=MAX_NAME, pattern=PARENT_PATTERN,
                              description="a collection path, or '' for the top, of at most "
                              f"{MAX_NAME} characters")]  # fmt: skip
JSON_OBJECT = Annotated[dict[str, Any], Field(description="a JSON object")]
DOCUMENT = Annotated[Any, *refusing({"type": "null"}), Field(description="any JSON value but null")]


def nullable(kind: Any) -> Any:
    return Annotated[kind | None, Field(description=f"{about(kind)}, or null")]


def _distinct(items: list) -> list:
    return list(dict.fromkeys(items))


def list_of(item: Any, least: int = 0, most: int = MAX_IDS, distinct: bool = False) -> Any:
    """A list; `distinct`: repeats dropped (the first kept): a clip named twice is edited once."""
    count = f"at least {least}" if least else "any number"
    words = f"a list of {count} (at most {most:,}) of: {about(item)}"
    kept = (AfterValidator(_distinct),) if distinct else ()
    return Annotated[list[item], Field(min_length=least, max_length=most, description=words), *kept]


def fixed(item: Any, n: int, words: str = "") -> Any:
    """A list of exactly `n` items (an axis, a quaternion, a pair)."""
    words = words or f"a list of {n} of: {about(item)}"
    return Annotated[list[item], Field(min_length=n, max_length=n, description=words)]


def map_of(value: Any, most: int = 1000, words: str = "") -> Any:
    words = words or f"an object of at most {most} names to: {about(value)}"
    return Annotated[dict[TEXT, value], Field(max_length=most, description=words)]


AXIS = Annotated[
    fixed(number(-1e6, 1e6), 3, "a direction [x, y, z] (numbers, not all 0)"),
    *refusing({"items": {"const": 0}}),
]


# --- bodies ---------------------------------------------------------------------------------------


class Body(BaseModel):
    """An object with these fields and no others. Its schema's `minProperties` and `oneOf` of
    required fields, where it states them, are checked here from the schema itself."""

    model_config = ConfigDict(strict=True, extra="forbid")

    @model_validator(mode="after")
    def _fields_given(self) -> Body:
        extra = self.model_config.get("json_schema_extra") or {}
        given = self.model_fields_set
        fields = list(type(self).model_fields)
        if len(given) < extra.get("minProperties", 0):
            raise PydanticCustomError(
                "min_properties", "nothing to change: give {fields}",
                {"fields": " and/or ".join(f'"{k}"' for k in fields)},
            )  # fmt: skip
        choices = [branch["required"] for branch in extra.get("oneOf", ())]
        if choices and sum(set(c) <= given for c in choices) != 1:
            raise PydanticCustomError(
                "one_of", "give {choices}: one of them, not both",
                {"choices": " or ".join(" and ".join(f'"{k}"' for k in c) for c in choices)},
            )  # fmt: skip
        return self


def _one_of(*fields: str) -> ConfigDict:
    return ConfigDict(json_schema_extra={"oneOf": [{"required": [f]} for f in fields]})


class NewCollection(Body):
    """A collection to create (and the levels above it)."""

    path: PATH


class CollectionChange(Body):
    """A collection's new name and/or new place ("parent": "" for the top)."""

    model_config = ConfigDict(json_schema_extra={"minProperties": 1})
    name: NAME = None
    parent: nullable(PARENT) = None


class Retarget(Body):
    """A clip retargeted onto another skeleton, as a new clip."""

    skeleton: whole("a skeleton id")
    collection: nullable(PATH) = None
    fps: nullable(FPS) = None
    mirror: FLAG = None


# Edit scripts: the kernel's table of commands and parameters, published as JSON Schema.


def _parameter(kind: Any) -> dict[str, Any]:
    if kind == "frame":
        return {"type": "integer", "minimum": 0, "description": "a frame number (from 0)"}
    if kind == "id":
        return {"type": "integer", "minimum": 1, "description": "an id"}
    if kind == "joints":
        return {"type": "array", "items": {"type": "string"}, "minItems": 1,
                "description": "a non-empty list of joint names"}  # fmt: skip
    if kind == "joint":
        return {"type": "string", "minLength": 1, "maxLength": 100,
                "description": "a standard joint name (the skeleton's joint map), e.g. right_wrist"}
    if kind == "chain":
        low, high = pose_edits.CHAIN_RANGE
        return {"type": "integer", "minimum": low, "maximum": high,
                "description": "how many joints above the joint may turn"}  # fmt: skip
    if kind in ("offset", "degrees"):
        most = pose_edits.OFFSET_M if kind == "offset" else pose_edits.MOST_DEGREES
        unit = "metres" if kind == "offset" else "degrees"
        return {"type": "array", "items": {"type": "number", "minimum": -most, "maximum": most},
                "minItems": 3, "maxItems": 3, "description": f"[x, y, z] in {unit}"}  # fmt: skip
    low, high = kind
    return {"type": "number", "minimum": low, "maximum": high}


def edit_script_schema() -> dict[str, Any]:
    """modb_kernel.edits' commands and their parameters as JSON Schema: what script_errors takes
    (a command's range over the clip, its frames, is checked as it is applied)."""
    commands = [
        {
            "type": "object",
            "title": op,
            "properties": {"op": {"const": op}} | {k: _parameter(kind) for k, (kind, _) in fields},
            "required": ["op", *(k for k, (_, required) in fields if required)],
        }
        for op, fields in ((op, p.items()) for op, p in KERNEL_COMMANDS.items())
    ]
    return {
        "type": "array",
        "minItems": 1,
        "items": {"oneOf": commands},
        "description": "an edit script: a non-empty list of commands, each an object with its "
        '"op" and that command\'s fields',
    }


def _kernel_check(commands: Any) -> Any:
    problems = script_errors(commands)
    if problems:
        raise PydanticCustomError("edit_script", "{problems}", {"problems": "; ".join(problems)})
    return commands


EDIT_SCRIPT = Annotated[Any, AfterValidator(_kernel_check), WithJsonSchema(edit_script_schema())]


class EditScript(Body):
    """An edit script to store (replacing one of that name)."""

    commands: EDIT_SCRIPT
    comment: nullable(text(2000, lines=True)) = None


CLIP_IDS = list_of(whole("a clip id"), 1, distinct=True)


class Targets(Body):
    """The clips an edit script is applied to: by ids, or every clip of a collection."""

    model_config = _one_of("clips", "collection")
    clips: CLIP_IDS = None
    collection: PATH = None


class NewRow(Body):
    """A models or graphs row."""

    name: TEXT
    kind: TEXT
    data: DOCUMENT
    meta: JSON_OBJECT = None
    skeleton_id: nullable(whole("a skeleton id")) = None


class RowChange(Body):
    """Fields of a models or graphs row to replace."""

    model_config = ConfigDict(json_schema_extra={"minProperties": 1})
    name: TEXT = None
    kind: TEXT = None
    data: DOCUMENT = None
    meta: JSON_OBJECT = None
    skeleton_id: nullable(whole("a skeleton id")) = None


class JointAxis(Body):
    """A standard joint's twist and swing axes in the skeleton's joint."""

    joint: TEXT
    twist: AXIS
    swing: AXIS


class JointAxes(Body):
    """The axes retargeting turns joints about, and the reference pose they were read in."""

    joints: map_of(JointAxis, words="an object of at most 1000 joints to their axes") = None
    pose: nullable(list_of(fixed(number(-1.0, 1.0), 4), 0, 100_000)) = None


class SkeletonMaps(Body):
    """A skeleton's joint map, mirror pairs and joint axes (the database checks the joints)."""

    joint_map: map_of(TEXT, most=100)
    mirror_pairs: list_of(fixed(TEXT, 2), most=1000)
    joint_axes: nullable(JointAxes) = None
    skeleton_id: whole("the skeleton's id") = None  # as GET answers, so it can be sent back


class VersionMeta(Body):
    """A clip version's whole new meta (annotations, tags)."""

    meta: JSON_OBJECT


# Jobs: what each kind takes, the arguments of its command (`modb graph build`, `modb retarget`,
# `modb edit apply`, `modb split`, `modb steps`, `modb align`, `modb model build`).


class ClipArguments(Body):
    """The clips a job works on: ids, or every clip of a collection (as it is queued)."""

    model_config = _one_of("clips", "from_collection")
    clips: CLIP_IDS = None
    from_collection: PATH = None


class BuildGraphArguments(Body):
    """A transition graph to build (`modb graph build`)."""

    name: TEXT
    profile: TEXT = None
    collection: nullable(PATH) = None
    min_turn_degrees: number(0.0, 180.0, unit="degrees") = None


class CollectionRetarget(Body):
    """A collection's clips retargeted onto another skeleton, as a job."""

    skeleton: whole("a skeleton id")
    collection: nullable(PATH) = None
    fps: nullable(FPS) = None
    mirrored: FLAG = None


class RetargetArguments(ClipArguments, CollectionRetarget):
    """Clips retargeted onto another skeleton (`modb retarget`)."""


class ApplyEditScriptArguments(ClipArguments):
    """A stored edit script applied to clips (`modb edit apply`)."""

    script: TEXT


class SplitArguments(ClipArguments):
    """Clips cut at their annotated segments (`modb split`)."""

    annotation: nullable(TEXT) = None
    collection: nullable(PATH) = None


class AnnotateStepsArguments(ClipArguments):
    """Clips whose steps to find (`modb steps`)."""


class Action(Body):
    """The action whose segments to find (`modb annotate --action NAME`)."""

    action: TEXT


class AnnotateActionArguments(ClipArguments, Action):
    """Clips whose action to find (`modb annotate --action`)."""


class Align(Body):
    """A primitive's examples in a collection to align in time."""

    primitive: TEXT
    collection: PATH


class ModelBuild(Body):
    """A motion model to build of a primitive's aligned examples."""

    collection: PATH
    primitive: TEXT
    seed: whole("a seed", 0, 2**31 - 1) = None
    variance: number(0.5, 0.999, unit="share of the variance") = None
    report: FLAG = None


class BuildModelArguments(ModelBuild):
    """A motion model to build, and its name (`modb model build`)."""

    name: TEXT


JOB_ARGUMENTS: dict[str, type[Body]] = {
    "build_graph": BuildGraphArguments,
    "retarget": RetargetArguments,
    "apply_edit_script": ApplyEditScriptArguments,
    "split_by_annotation": SplitArguments,
    "annotate_steps": AnnotateStepsArguments,
    "annotate_action": AnnotateActionArguments,
    "align": Align,
    "build_model": BuildModelArguments,
}


def _job(kind: str, arguments: type[Body]) -> type[Body]:
    name = "".join(part.title() for part in kind.split("_")) + "Job"
    return create_model(
        name,
        __base__=Body,
        __doc__=f"A job of kind {kind}: its arguments, and the jobs it waits for",
        kind=(Literal[kind], ...),
        arguments=(arguments, ...),
        after=(list_of(whole("a job id"), 1), None),
    )


JOB = Annotated[
    Union[tuple(_job(kind, arguments) for kind, arguments in JOB_ARGUMENTS.items())],  # noqa: UP007
    Field(discriminator="kind", description="a job: its kind, arguments and the jobs it waits for"),
]


# --- the published schema -------------------------------------------------------------------------


class PublishedSchema(GenerateJsonSchema):
    """pydantic's JSON Schema, as /api/openapi.json publishes it: no titles on fields (a model keeps
    its own), no defaults (a field left out is left out: the handler decides), and an object of
    names to values says its names' pattern in propertyNames (pydantic's patternProperties would
    leave the names it does not match unchecked)."""

    def field_title_should_be_set(self, schema: Any) -> bool:
        return False

    def default_schema(self, schema: Any) -> dict[str, Any]:
        return self.generate_inner(schema["schema"])

    def dict_schema(self, schema: Any) -> dict[str, Any]:
        out = super().dict_schema(schema)
        patterns = out.pop("patternProperties", None)
        if patterns:
            ((pattern, values),) = patterns.items()
            out["additionalProperties"] = values
            out["propertyNames"] = {**out.get("propertyNames", {}), "pattern": pattern}
        return out

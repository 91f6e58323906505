"""Trace reader: parses and validates a whole `.jsonl` trace before anything runs.

The format is docs/spec.md section 12 (and ../shared/TRACE-FORMAT.md). Every
error names the line and the field; a bad trace raises `TraceError` and the
caller writes nothing. The painter's reader (painter/trace/src/read.rs) must
accept and reject exactly the same traces, and refuse each bad one on the same
line with the same error kind (spec 12.2); the wording is each reader's own.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field

from .layer_rules import MAX_LAYERS, MODEL_START, OPS, LayerOp, check_op, model_apply, name_problem, to_f32

NAME_RE = re.compile(r"[A-Za-z0-9._-]+")  # used with fullmatch: "$" would admit a final newline
SHAPES = ("sphere", "cylinder", "box", "cone", "noise")
MODES = ("paint", "erase", "recolor", "mix", "pickup")
MAX_DEPTH_LIMIT = 28
MAX_CAPACITY = 0xFFFF_FFF8  # largest multiple of 8 below NONE
MAX_IMAGE_SIZE = 16384
MAX_ROOTS = 1 << 24
MAX_STAMPS_PER_SEGMENT = 65536
# Lines nested deeper than this are refused before they are parsed (spec
# 12.2), below the depth where either reader's JSON library stops on its own
# (serde_json: 128; Python: the recursion limit).
MAX_NESTING = 64
# An integer literal with more digits is beyond f64 (and refused as such)
# whatever its digits are; JSON has no leading zeros.
MAX_F64_INT_DIGITS = 309
SPACING_RANGE = (0.01, 100.0)
ASPECT_RANGE = (1e-3, 1e3)
NOISE_OCTAVES_RANGE = (1, 8)
NOISE_FREQUENCY_MAX = 1e6
HALF_PI = math.pi / 2
LIGHT_INTENSITY_MAX = 16.0


# What went wrong, as a short stable code (spec 12.2): both readers must give
# the same line and kind for a refused trace; the message text is their own.
KINDS = ("io", "utf8", "json", "header", "type", "missing", "range", "budget", "event", "event-order", "name", "layer", "import")


class TraceError(ValueError):
    """A trace that must not be replayed: `line` (1-based; 0 when the file
    cannot be read), `kind` (one of KINDS) and a message naming the field."""

    def __init__(self, line: int, kind: str, text: str):
        assert kind in KINDS, kind
        super().__init__(f"line {line}: {text}" if line else text)
        self.line = line
        self.kind = kind


@dataclass(frozen=True)
class Canvas:
    roots: tuple[int, int, int]
    max_depth: int
    root_size: float
    capacity: int


@dataclass(frozen=True)
class Noise:
    frequency: float = 1.0
    octaves: int = 4
    seed: int = 0
    gain: float = 0.5


@dataclass(frozen=True)
class Mirror:
    """Mirror painting (spec 8.11): the planes through `centre` (canvas
    units) normal to the axes set in `axes` (x, y, z)."""

    axes: tuple[bool, bool, bool]
    centre: tuple[float, float, float]

    def copies(self) -> tuple[int, ...]:
        """The mirrored copies as axis masks (bit a: axis a mirrored), in
        increasing order: every non-empty combination of the set axes."""
        on = sum(1 << a for a in range(3) if self.axes[a])
        return tuple(m for m in range(1, 8) if m & ~on == 0)


@dataclass(frozen=True)
class Brush:
    shape: str
    mode: str
    radius: float
    color: tuple[float, float, float]
    opacity: float
    hardness: float
    spacing: float = 0.25
    mix_ratio: float = 1.0
    pickup_rate: float = 0.25
    aspect: tuple[float, float, float] = (1.0, 1.0, 1.0)
    noise: Noise = field(default_factory=Noise)
    # Not a brush field of the trace: the last `mirror` event's planes, set
    # on the brush when a stroke begins (spec 8.11).
    mirror: Mirror | None = None


@dataclass(frozen=True)
class Sample:
    p: tuple[float, float, float]
    pressure: float = 1.0
    q: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Camera:
    eye: tuple[float, float, float]
    q: tuple[float, float, float, float]
    fov: tuple[float, float, float, float]
    size: tuple[int, int]
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Light:
    """The `light` event (spec 6.1): lighting on or off; when on, the
    direction towards the light in canvas space (as given: normalised when
    rendering), its intensity, the ambient term and whether shadow rays are
    cast."""

    on: bool = True
    dir: tuple[float, float, float] = (0.0, 0.0, 0.0)
    intensity: float = 0.8
    ambient: float = 0.3
    shadows: bool = False


@dataclass(frozen=True)
class Event:
    """One event. `kind` is the `ev` string; `value` is a Brush, Sample,
    Camera, Light, a name (render/snapshot) or None."""

    line: int
    t: float
    kind: str
    value: object = None


@dataclass(frozen=True)
class Trace:
    canvas: Canvas
    meta: dict
    events: tuple[Event, ...]
    warnings: tuple[str, ...]
    version: int = 1


def _fail(line: int, fld: str, msg: str, kind: str = "range") -> TraceError:
    return TraceError(line, kind, f"{fld}: {msg}")


def _finite(line: int, fld: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _fail(line, fld, f"expected a number, got {json.dumps(v)}", "type")
    x = float(v)  # finite: the JSON reading refused literals beyond f64
    # Subnormal numbers are read as 0: XLA flushes them, numpy and Rust do
    # not, and no painting needs them (spec 12.2).
    return 0.0 if abs(x) < 2.2250738585072014e-308 else x


def _int(line: int, fld: str, v, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _fail(line, fld, f"expected an integer, got {json.dumps(v)}", "type")
    if isinstance(v, float) and v != math.floor(v):
        raise _fail(line, fld, f"expected an integer, got {v!r}", "type")
    i = int(v)
    if not lo <= i <= hi:
        raise _fail(line, fld, f"{i} is outside [{lo}, {hi}]")
    return i


def _ranged(line: int, fld: str, v, lo: float, hi: float) -> float:
    x = _finite(line, fld, v)
    if not lo <= x <= hi:
        raise _fail(line, fld, f"{x!r} is outside [{lo!r}, {hi!r}]")
    return x


def _vec(line: int, fld: str, v, n: int) -> list:
    if not isinstance(v, list) or len(v) != n:
        raise _fail(line, fld, f"expected an array of {n} numbers", "type")
    return v


def _vec_finite(line: int, fld: str, v, n: int) -> tuple:
    return tuple(_finite(line, f"{fld}[{i}]", x) for i, x in enumerate(_vec(line, fld, v, n)))


def _vec_unit(line: int, fld: str, v, n: int) -> tuple:
    return tuple(_ranged(line, f"{fld}[{i}]", x, 0.0, 1.0) for i, x in enumerate(_vec(line, fld, v, n)))


def _quat(line: int, fld: str, v) -> tuple:
    q = _vec_finite(line, fld, v, 4)
    n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
    if not math.isfinite(n2) or math.sqrt(n2) < 1e-12:
        raise _fail(line, fld, "zero or non-finite quaternion")
    return q


def _require(line: int, obj: dict, key: str, prefix: str = ""):
    if key not in obj:
        raise _fail(line, prefix + key, "missing", "missing")
    return obj[key]


def _name(line: int, v) -> str:
    if not isinstance(v, str) or not NAME_RE.fullmatch(v) or v in (".", ".."):
        raise _fail(line, "name", f"{json.dumps(v)} is not a name of [A-Za-z0-9._-]+ (no paths)", "name")
    return v


def parse_canvas(line: int, obj) -> Canvas:
    if not isinstance(obj, dict):
        raise _fail(line, "canvas", "expected an object", "type")
    roots = tuple(
        _int(line, f"canvas.roots[{i}]", x, 1, 1 << 16)
        for i, x in enumerate(_vec(line, "canvas.roots", _require(line, obj, "roots", "canvas."), 3))
    )
    max_depth = _int(line, "canvas.max_depth", _require(line, obj, "max_depth", "canvas."), 0, MAX_DEPTH_LIMIT)
    for i, r in enumerate(roots):
        if r << max_depth > 1 << 32:
            raise _fail(line, f"canvas.roots[{i}]", f"{r} roots of depth {max_depth} exceed the u32 lattice")
    root_size = _finite(line, "canvas.root_size", _require(line, obj, "root_size", "canvas."))
    if not 1e-9 <= root_size <= 1e12:
        raise _fail(line, "canvas.root_size", f"{root_size!r} is outside [1e-09, 1e+12]")
    n_roots = roots[0] * roots[1] * roots[2]
    if n_roots > MAX_ROOTS:
        raise _fail(line, "canvas.roots", f"{n_roots} roots are more than the {MAX_ROOTS} allowed", "budget")
    padded = (n_roots + 7) // 8 * 8
    capacity = _int(line, "canvas.capacity", _require(line, obj, "capacity", "canvas."), 8, MAX_CAPACITY)
    if capacity < padded:
        raise _fail(line, "canvas.capacity", f"{capacity} is below the {padded} cells the roots need", "budget")
    return Canvas(roots, max_depth, root_size, capacity)


def parse_brush(line: int, obj: dict) -> Brush:
    shape = _require(line, obj, "shape")
    if shape not in SHAPES:
        raise _fail(line, "shape", f"{json.dumps(shape)} is not one of {', '.join(SHAPES)}")
    mode = _require(line, obj, "mode")
    if mode not in MODES:
        raise _fail(line, "mode", f"{json.dumps(mode)} is not one of {', '.join(MODES)}")
    radius = _finite(line, "radius", _require(line, obj, "radius"))
    if radius <= 0:
        raise _fail(line, "radius", f"{radius!r} must be > 0")
    color = _vec_unit(line, "color", _require(line, obj, "color"), 3)
    opacity = _ranged(line, "opacity", _require(line, obj, "opacity"), 0.0, 1.0)
    hardness = _ranged(line, "hardness", _require(line, obj, "hardness"), 0.0, 1.0)
    kw = {}
    if "spacing" in obj:
        kw["spacing"] = _ranged(line, "spacing", obj["spacing"], *SPACING_RANGE)
    if "mix_ratio" in obj:
        kw["mix_ratio"] = _ranged(line, "mix_ratio", obj["mix_ratio"], 0.0, 1.0)
    if "pickup_rate" in obj:
        kw["pickup_rate"] = _ranged(line, "pickup_rate", obj["pickup_rate"], 0.0, 1.0)
    if "aspect" in obj:
        kw["aspect"] = tuple(
            _ranged(line, f"aspect[{i}]", x, *ASPECT_RANGE)
            for i, x in enumerate(_vec(line, "aspect", obj["aspect"], 3))
        )
    if "noise" in obj:
        n = obj["noise"]
        if not isinstance(n, dict):
            raise _fail(line, "noise", "expected an object", "type")
        nkw = {}
        if "frequency" in n:
            nkw["frequency"] = _finite(line, "noise.frequency", n["frequency"])
            if not 0 < nkw["frequency"] <= NOISE_FREQUENCY_MAX:
                raise _fail(line, "noise.frequency", f"{nkw['frequency']!r} is outside (0, {NOISE_FREQUENCY_MAX:g}]")
        if "octaves" in n:
            nkw["octaves"] = _int(line, "noise.octaves", n["octaves"], *NOISE_OCTAVES_RANGE)
        if "seed" in n:
            nkw["seed"] = _int(line, "noise.seed", n["seed"], 0, 0xFFFF_FFFF)
        if "gain" in n:
            nkw["gain"] = _ranged(line, "noise.gain", n["gain"], 0.0, 1.0)
        kw["noise"] = Noise(**nkw)
    return Brush(shape, mode, radius, color, opacity, hardness, **kw)


def parse_mirror(line: int, obj: dict) -> Mirror:
    """The `mirror` event (spec 8.11): `axes` 3 booleans, `centre` 3 numbers."""
    axes = _vec(line, "axes", _require(line, obj, "axes"), 3)
    for i, x in enumerate(axes):
        if not isinstance(x, bool):
            raise _fail(line, f"axes[{i}]", f"expected true or false, got {json.dumps(x)}", "type")
    return Mirror(tuple(axes), _vec_finite(line, "centre", _require(line, obj, "centre"), 3))


def parse_sample(line: int, obj: dict) -> Sample:
    p = _vec_finite(line, "p", _require(line, obj, "p"), 3)
    kw = {}
    if "pressure" in obj:
        kw["pressure"] = _ranged(line, "pressure", obj["pressure"], 0.0, 1.0)
    if "q" in obj:
        kw["q"] = _quat(line, "q", obj["q"])
    return Sample(p, **kw)


def parse_camera(line: int, obj: dict) -> Camera:
    eye = _vec_finite(line, "eye", _require(line, obj, "eye"), 3)
    q = _quat(line, "q", _require(line, obj, "q"))
    fov = tuple(
        _finite(line, f"fov[{i}]", x) for i, x in enumerate(_vec(line, "fov", _require(line, obj, "fov"), 4))
    )
    for i, a in enumerate(fov):
        if not -HALF_PI < a < HALF_PI:
            raise _fail(line, f"fov[{i}]", f"{a!r} is outside (-pi/2, pi/2)")
    left, right, up, down = fov
    if not left < right:
        raise _fail(line, "fov", "angles not ordered: left must be < right")
    if not down < up:
        raise _fail(line, "fov", "angles not ordered: down must be < up")
    size = tuple(
        _int(line, f"size[{i}]", x, 1, MAX_IMAGE_SIZE)
        for i, x in enumerate(_vec(line, "size", _require(line, obj, "size"), 2))
    )
    kw = {}
    if "background" in obj:
        kw["background"] = _vec_unit(line, "background", obj["background"], 3)
    return Camera(eye, q, fov, size, **kw)


def _bool(line: int, fld: str, v) -> bool:
    if not isinstance(v, bool):
        raise _fail(line, fld, f"expected true or false, got {json.dumps(v)}", "type")
    return v


def parse_light(line: int, obj: dict) -> Light:
    on = _bool(line, "on", obj["on"]) if "on" in obj else True
    if not on:
        return Light(on=False)
    d = _vec_finite(line, "dir", _require(line, obj, "dir"), 3)
    n2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    if not math.isfinite(n2) or math.sqrt(n2) < 1e-12:
        raise _fail(line, "dir", "zero or non-finite direction")
    kw = {}
    if "intensity" in obj:
        kw["intensity"] = _ranged(line, "intensity", obj["intensity"], 0.0, LIGHT_INTENSITY_MAX)
    if "ambient" in obj:
        kw["ambient"] = _ranged(line, "ambient", obj["ambient"], 0.0, 1.0)
    if "shadows" in obj:
        kw["shadows"] = _bool(line, "shadows", obj["shadows"])
    return Light(True, d, **kw)


def _layer_ref(line: int, obj: dict) -> str:
    v = _require(line, obj, "layer")
    if not isinstance(v, str):
        raise _fail(line, "layer", f"expected a layer name, got {json.dumps(v)}", "type")
    return v


def _layer_name(line: int, obj: dict) -> str:
    v = _require(line, obj, "name")
    if not isinstance(v, str):
        raise _fail(line, "name", f"expected a string, got {json.dumps(v)}", "type")
    why = name_problem(v)
    if why:
        raise _fail(line, "name", why)
    return v


def parse_layer(line: int, obj: dict) -> LayerOp:
    """The `layer` event (spec 14.2): `op`, then its fields in order."""
    op = _require(line, obj, "op")
    if not isinstance(op, str):
        raise _fail(line, "op", f"expected a string, got {json.dumps(op)}", "type")
    if op not in OPS:
        raise _fail(line, "op", f"{json.dumps(op)} is not one of {', '.join(OPS)}")
    if op == "add":
        return LayerOp(op, name=_layer_name(line, obj))
    layer = _layer_ref(line, obj)
    if op in ("rename", "duplicate"):
        return LayerOp(op, layer=layer, name=_layer_name(line, obj))
    if op == "move":
        return LayerOp(op, layer=layer, to=_int(line, "to", _require(line, obj, "to"), 0, MAX_LAYERS - 1))
    if op == "set":
        visible = _bool(line, "visible", obj["visible"]) if "visible" in obj else None
        opacity = to_f32(_ranged(line, "opacity", obj["opacity"], 0.0, 1.0)) if "opacity" in obj else None
        locked = _bool(line, "locked", obj["locked"]) if "locked" in obj else None
        if visible is None and opacity is None and locked is None:
            raise _fail(line, "visible", "set needs visible, opacity or locked", "missing")
        return LayerOp(op, layer=layer, visible=visible, opacity=opacity, locked=locked)
    return LayerOp(op, layer=layer)


SHA256_RE = re.compile(r"[0-9a-f]{64}")


def parse_import(line: int, obj: dict):
    """The fields of an `import` event (spec 15.2): `file`, `sha256`,
    optional `name`. read_import then reads the file."""
    file = _require(line, obj, "file")
    if not isinstance(file, str):
        raise _fail(line, "file", f"expected a string, got {json.dumps(file)}", "type")
    parts = file.split("/")
    if not 1 <= len(parts) <= 8 or not all(NAME_RE.fullmatch(p) and p not in (".", "..") for p in parts):
        raise _fail(line, "file", f"{json.dumps(file)} is not a relative path of 1 to 8 plain names", "name")
    digest = _require(line, obj, "sha256")
    if not isinstance(digest, str):
        raise _fail(line, "sha256", f"expected a string, got {json.dumps(digest)}", "type")
    if not SHA256_RE.fullmatch(digest):
        raise _fail(line, "sha256", f"{json.dumps(digest)} is not 64 lowercase hexadecimal digits")
    name = None
    if "name" in obj:
        name = obj["name"]
        if not isinstance(name, str):
            raise _fail(line, "name", f"expected a string, got {json.dumps(name)}", "type")
        why = name_problem(name)
        if why:
            raise _fail(line, "name", why)
    return file, digest, name


def read_import(line: int, file: str, digest: str, name, canvas, resolve):
    """The voxel set of an `import` event, through `resolve(file) -> bytes`."""
    from .voxelset import Import, parse, sha256

    if resolve is None:
        raise _fail(line, "file", "this trace was not read from a folder, so its imports cannot be found", "import")
    try:
        data = resolve(file)
    except OSError as e:
        raise _fail(line, "file", f"cannot read {file}: {e.strerror or e}", "import") from None
    got = sha256(data)
    if got != digest:
        raise _fail(line, "sha256", f"{file} has SHA-256 {got}, not the {digest} the trace names (the file changed)", "import")
    try:
        voxels = parse(data, canvas)
    except ValueError as e:
        raise _fail(line, "file", f"{file} is not a voxel set for this canvas: {e}", "import") from None
    return Import(file, digest, name, voxels)


def folder_resolver(folder: str):
    """Imports resolved against `folder` (the trace's own)."""
    import os

    def resolve(file: str) -> bytes:
        with open(os.path.join(folder, *file.split("/")), "rb") as f:
            return f.read()

    return resolve


def stamp_count_bound(brush: Brush, a: Sample, b: Sample) -> float:
    """An upper bound on the stamps one segment places (spec 8.4), used to
    refuse absurd traces before anything runs: floor(L / (spacing * r_min))
    + 1, 1 for a zero-length segment, infinite when the quotient overflows
    (samples 1e308 apart)."""
    if brush.shape == "sphere":
        return 1
    d = [b.p[i] - a.p[i] for i in range(3)]
    length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    if length == 0:
        return 1
    r_min = brush.radius * (0.25 + 0.75 * min(a.pressure, b.pressure))
    quotient = length / (brush.spacing * r_min)
    return math.floor(quotient) + 1 if math.isfinite(quotient) else math.inf


class _NotJson(ValueError):
    """A line that the JSON rules of spec 12.2 refuse although Python's
    `json` module would read it."""


def _parse_int(text: str) -> int:
    """Integers are exact, but one beyond f64's range is refused, as a
    float literal beyond it is (serde_json refuses both)."""
    if len(text) - text.startswith("-") > MAX_F64_INT_DIGITS:
        raise _NotJson("number out of range")
    i = int(text)
    try:
        float(i)
    except OverflowError:
        raise _NotJson("number out of range") from None
    return i


def _parse_float(text: str) -> float:
    x = float(text)
    if math.isinf(x):
        raise _NotJson("number out of range")
    return x


def _parse_constant(text: str):
    raise _NotJson(f"{text} is not a JSON number")


def _no_lone_surrogates(v) -> None:
    """Refuse a string holding an unpaired surrogate escape such as
    "\\ud800": it is no Unicode text, and serde_json refuses it. Objects are
    checked as they are built (`_object`), so that a repeated key's earlier
    value is checked too."""
    if isinstance(v, str):
        if any("\ud800" <= c <= "\udfff" for c in v):
            raise _NotJson("a string holds an unpaired surrogate")
    elif isinstance(v, list):
        for x in v:
            _no_lone_surrogates(x)


def _object(pairs: list) -> dict:
    for k, v in pairs:
        _no_lone_surrogates(k)
        _no_lone_surrogates(v)
    return dict(pairs)  # a repeated key: its first place, its last value


# Lines where a surrogate escape or a number literal beyond f64 could hide
# take the slower reading with every check (most lines of a trace do not;
# the verdict is the same either way). A literal beyond f64 (>= 1.8e308) has
# an exponent of three or more digits, or else at least 309 - 99 = 210
# digits in a row.
_EXPONENT_3 = re.compile(r"[eE]\+?\d{3}")
_DIGITS_200 = re.compile(r"\d{200}")


def _suspect(raw: str) -> bool:
    return "\\u" in raw or _EXPONENT_3.search(raw) is not None or (len(raw) >= 200 and _DIGITS_200.search(raw) is not None)


def _json_line(raw: str):
    """One trace line as JSON under spec 12.2's rules (raises
    json.JSONDecodeError or _NotJson)."""
    if not _suspect(raw):
        return json.loads(raw, parse_constant=_parse_constant)
    obj = json.loads(raw, parse_int=_parse_int, parse_float=_parse_float, parse_constant=_parse_constant, object_pairs_hook=_object)
    _no_lone_surrogates(obj)
    return obj


def _nesting_depth(line: str) -> int:
    """The deepest [/{ nesting of a line outside strings (a '"' toggles a
    string unless escaped by a backslash inside one); spec 12.2."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in line:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def parse_trace(text: str, resolve=None) -> Trace:
    """Parse and validate a whole trace. Raises TraceError naming the line.
    `resolve(file) -> bytes` reads the files of `import` events (spec 15.2;
    read_trace resolves them in the trace's folder)."""
    lines = text.split("\n")
    header = None
    events: list[Event] = []
    warnings: list[str] = []
    brush: Brush | None = None
    in_stroke = False
    stroke_begin_line = 0
    last_sample: Sample | None = None
    last_t = 0.0
    # The undo stack as a model (spec 12.2, 14.2): a step is None (a stroke)
    # or the layers' (names, locks, selection) before and after a layer event.
    done: list = []
    undone: list = []
    layers = MODEL_START
    version = 1
    names = {"render": set(), "snapshot": set()}
    for lineno, raw in enumerate(lines, start=1):
        if raw.strip() == "":
            continue
        if _nesting_depth(raw) > MAX_NESTING:
            raise TraceError(lineno, "json", f"not valid JSON: brackets nested deeper than {MAX_NESTING} levels")
        try:
            obj = _json_line(raw)
        except json.JSONDecodeError as e:
            raise TraceError(lineno, "json", f"not valid JSON: {e.msg} (column {e.colno})") from None
        except _NotJson as e:
            raise TraceError(lineno, "json", f"not valid JSON: {e}") from None
        if not isinstance(obj, dict):
            raise TraceError(lineno, "type", "expected a JSON object")
        if header is None:
            if obj.get("format") != "ddo-trace":
                raise _fail(lineno, "format", 'the first line must be a header with "format": "ddo-trace"', "header")
            if "version" not in obj:
                raise _fail(lineno, "version", "missing", "missing")
            version = obj["version"]
            if isinstance(version, bool) or version not in (1, 2):
                raise _fail(lineno, "version", f"{json.dumps(version)} is not supported (this reader knows versions 1 and 2)", "header")
            version = int(version)
            canvas = parse_canvas(lineno, _require(lineno, obj, "canvas"))
            meta = obj.get("meta", {})
            if not isinstance(meta, dict):
                raise _fail(lineno, "meta", "expected an object", "type")
            header = (canvas, meta)
            continue
        ev = _require(lineno, obj, "ev")
        if not isinstance(ev, str):
            raise _fail(lineno, "ev", f"expected a string, got {json.dumps(ev)}", "type")
        t = _finite(lineno, "t", _require(lineno, obj, "t"))
        if t < 0:
            raise _fail(lineno, "t", f"{t!r} must be >= 0")
        if t < last_t:
            raise _fail(lineno, "t", f"{t!r} is earlier than the previous event's {last_t!r}", "event-order")
        last_t = t
        value = None
        if ev == "brush":
            if in_stroke:
                raise _fail(lineno, "ev", "brush inside a stroke (brushes change between strokes)", "event-order")
            brush = value = parse_brush(lineno, obj)
        elif ev == "stroke_begin":
            if in_stroke:
                raise _fail(lineno, "ev", f"stroke_begin inside the stroke begun on line {stroke_begin_line}", "event-order")
            if brush is None:
                raise _fail(lineno, "ev", "stroke_begin before any brush event", "event-order")
            if layers[1][layers[2]]:
                raise _fail(lineno, "ev", f"the selected layer {layers[0][layers[2]]!r} is locked", "layer")
            in_stroke, stroke_begin_line, last_sample = True, lineno, None
        elif ev == "sample":
            if not in_stroke:
                raise _fail(lineno, "ev", "sample outside a stroke", "event-order")
            value = parse_sample(lineno, obj)
            if last_sample is not None and stamp_count_bound(brush, last_sample, value) > MAX_STAMPS_PER_SEGMENT:
                raise _fail(
                    lineno,
                    "p",
                    f"this segment would place more than {MAX_STAMPS_PER_SEGMENT} stamps "
                    "(samples too far apart for the brush radius and spacing)",
                    "budget",
                )
            last_sample = value
        elif ev == "stroke_end":
            if not in_stroke:
                raise _fail(lineno, "ev", "stroke_end outside a stroke", "event-order")
            in_stroke = False
            done.append(None)
            undone.clear()
        elif ev == "camera":
            value = parse_camera(lineno, obj)
        elif ev == "light":
            value = parse_light(lineno, obj)
        elif ev == "mirror":
            if in_stroke:
                raise _fail(lineno, "ev", "mirror inside a stroke (mirror planes change between strokes)", "event-order")
            value = parse_mirror(lineno, obj)
        elif ev in ("render", "snapshot"):
            value = _name(lineno, _require(lineno, obj, "name"))
            if value in names[ev]:
                raise _fail(lineno, "name", f"{json.dumps(value)} is already used by an earlier {ev}", "name")
            names[ev].add(value)
            if ev == "render" and not any(e.kind == "camera" for e in events):
                raise _fail(lineno, "ev", "render before any camera event", "event-order")
        elif ev in ("undo", "redo"):
            if in_stroke:
                raise _fail(lineno, "ev", f"{ev} inside a stroke", "event-order")
            if ev == "undo":
                if not done:
                    raise _fail(lineno, "ev", "undo with no stroke to undo", "event-order")
                step = done.pop()
                if step is not None:
                    layers = step[0]
                undone.append(step)
            else:
                if not undone:
                    raise _fail(lineno, "ev", "redo with nothing undone", "event-order")
                step = undone.pop()
                if step is not None:
                    layers = step[1]
                done.append(step)
        elif ev == "import":
            if in_stroke:
                raise _fail(lineno, "ev", "import inside a stroke (imports come between strokes)", "event-order")
            file, digest, label = parse_import(lineno, obj)
            if layers[1][layers[2]]:
                raise _fail(lineno, "ev", f"the selected layer {layers[0][layers[2]]!r} is locked", "layer")
            value = read_import(lineno, file, digest, label, header[0], resolve)
            done.append(None)
            undone.clear()
        elif ev == "layer" and version == 2:
            if in_stroke:
                raise _fail(lineno, "ev", "layer inside a stroke (layers change between strokes)", "event-order")
            value = parse_layer(lineno, obj)
            why = check_op(list(layers[0]), list(layers[1]), value)
            if why:
                raise TraceError(lineno, "layer", why)
            after = model_apply(layers, value)
            if value.op != "select":
                done.append((layers, after))
                undone.clear()
            layers = after
        else:
            raise _fail(lineno, "ev", f"unknown event {json.dumps(ev)}", "event")
        events.append(Event(lineno, t, ev, value))
    if header is None:
        raise TraceError(1, "header", "format: empty trace (a header line is required)")
    if in_stroke:
        warnings.append(f"line {stroke_begin_line}: the trace ends inside this stroke; it is ended here")
        events.append(Event(len(lines), last_t, "stroke_end", None))
    return Trace(header[0], header[1], tuple(events), tuple(warnings), version)


def read_trace(path) -> Trace:
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise TraceError(0, "io", f"cannot read {path}: {e.strerror}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise TraceError(line, "utf8", "not valid UTF-8") from None
    import os

    return parse_trace(text, folder_resolver(os.path.dirname(os.path.abspath(path))))

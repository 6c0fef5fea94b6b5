"""Import of Player/Stage 4 world files (``.world``) as mazes.

The world-file syntax is read by a small tokenizer and parser: words, numbers, ``"strings"``,
``[ ]`` tuples, ``( )`` bodies and ``#`` comments to the end of the line; ``include "file"``
(resolved relative to the including file, then to the main world file's folder as Stage does);
``define NEWTYPE BASETYPE ( ... )`` with property inheritance along the chain of types; and model
instances ``TYPE ( ... )``, nested or not. Global settings (``resolution``, ``interval_sim``,
``threads``, ...), the ``window`` block, and ``name``, ``color`` and every other property not
listed below are read but ignored.

How models become maze parts (lengths in metres, angles in degrees as in Stage):

* A model with a ``bitmap "file.png"`` property (a ``floorplan``) is a **bitmap floorplan**. The
  image is read with Pillow (PNG or any other format it knows) and turned grey as the mean of
  R, G, B on a 0..255 scale (alpha ignored; :func:`bitmap_grey`); pixels ``<= 127`` are
  obstacles. As in Stage (``BlockGroup::CalcSize``), the bounding box of the dark
  pixels — not the whole image — is scaled to the model's ``size [sx sy ...]`` and centred on its
  ``pose [x y z a]`` (shifted by ``origin`` if given); ``bitmap_extent="image"`` scales the whole
  image instead. Dark pixels are merged into rectangles (pixels need not be square).
  ``boundary 1`` adds Stage's four thin walls (0.01 pixel thick) along the footprint's edges.
  Stage's ``floorplan`` template has ``obstacle_return 0``: its bitmap blocks sonar rays but not
  the robot. Here floorplans are solid walls for both (the robot collides with them).
* A model without bitmap whose type derives (through ``define``) from ``position`` is a **robot**:
  its ``pose [x y z a]`` (default all 0) becomes a start pose ``(x, y, radians(a))``. Its child
  models (sonars, blocks, ...) are ignored.
* Any other model with both ``size`` and ``pose`` (after inheritance) is a **rectangular wall** of
  footprint ``size[0] x size[1]`` centred on ``pose`` (plus ``origin``), unless it has
  ``obstacle_return 0`` (then it is skipped: the robot passes through it in Stage). Its
  ``block`` shapes are ignored: the footprint is the ``size`` rectangle. Models lacking ``size``
  or ``pose`` are skipped.
* Nested models are placed relative to their parent's pose (and rotation); the parent need not be
  a wall itself.
* Every rotation ``a`` (pose and origin) must be a multiple of 90 degrees (extents are swapped for
  90 and 270); anything else is an error naming the file and line of the model.

The maze has ``outside_is_wall = False``; its bounds are the bounding box of the walls (grown to
hold every start). Coordinates are rounded to 1e-9 m to remove binary noise from ``x +/- w/2``.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.model import Maze, merge_cells
from mbn.world.mazes.validate import read_text, validate_maze

__all__ = [
    "StageModel",
    "Token",
    "bitmap_grey",
    "parse_stage_world",
    "read_stage_world",
    "tokenize",
]

# ---------------------------------------------------------------------------------------------
# tokens

_TOKEN_RE = re.compile(
    r"""
    (?P<comment>\#[^\n]*)
  | (?P<newline>\n)
  | (?P<space>[ \t\r\f\v]+)
  | (?P<string>"[^"\n]*")
  | (?P<number>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?(?![A-Za-z_]))
  | (?P<word>[A-Za-z_][A-Za-z0-9_.\-\[\]]*)
  | (?P<punct>[\[\]()])
    """,
    re.VERBOSE,
)


@dataclass(frozen=True)
class Token:
    """One token: ``kind`` is ``word``, ``number``, ``string`` or ``punct``; ``value`` its text
    (without quotes for strings); ``file`` and ``line`` where it stands."""

    kind: str
    value: str
    file: str
    line: int

    @property
    def where(self) -> str:
        """``"file:line"``."""
        return f"{self.file}:{self.line}"


def tokenize(text: str, file: str = "<world>") -> list[Token]:
    """Split world-file text into tokens (comments and white space dropped)."""
    tokens: list[Token] = []
    line = 1
    pos = 0
    while pos < len(text):
        match = _TOKEN_RE.match(text, pos)
        if match is None:
            ch = text[pos]
            if ch == '"':
                raise MbnInputError(f"{file}:{line}: unterminated string")
            raise MbnInputError(f"{file}:{line}: unexpected character {ch!r}")
        kind = match.lastgroup
        value = match.group()
        if kind == "newline":
            line += 1
        elif kind in ("word", "number", "punct"):
            tokens.append(Token(str(kind), value, file, line))
        elif kind == "string":
            tokens.append(Token("string", value[1:-1], file, line))
        pos = match.end()
    return tokens


# ---------------------------------------------------------------------------------------------
# the parsed file

Value = float | str
#: Properties of a model: name -> (values, "file:line" of the property).
Props = dict[str, tuple[list[Value], str]]


@dataclass
class StageModel:
    """A model instance: its type, own properties (with the line of each), children, and where
    it was written."""

    type: str
    props: Props
    children: list[StageModel]
    where: str


@dataclass
class _Define:
    base: str
    props: Props
    children: list[StageModel]
    where: str


@dataclass
class _World:
    defines: dict[str, _Define] = field(default_factory=dict)
    models: list[StageModel] = field(default_factory=list)
    main_dir: Path = Path(".")
    including: list[Path] = field(default_factory=list)


class _Parser:
    """Recursive-descent parser over the tokens of one file (includes are parsed recursively)."""

    def __init__(self, tokens: list[Token], path: Path, world: _World) -> None:
        self.tokens = tokens
        self.pos = 0
        self.path = path
        self.world = world

    def _peek(self, offset: int = 0) -> Token | None:
        i = self.pos + offset
        return self.tokens[i] if i < len(self.tokens) else None

    def _next(self, what: str) -> Token:
        tok = self._peek()
        if tok is None:
            last = self.tokens[-1].where if self.tokens else f"{self.path}:1"
            raise MbnInputError(f"{last}: unexpected end of file (expected {what})")
        self.pos += 1
        return tok

    def _expect(self, kind: str, value: str | None, what: str) -> Token:
        tok = self._next(what)
        if tok.kind != kind or (value is not None and tok.value != value):
            raise MbnInputError(f"{tok.where}: expected {what}, got {tok.value!r}")
        return tok

    def parse_file(self) -> None:
        while self._peek() is not None:
            tok = self._next("a statement")
            if tok.kind != "word":
                raise MbnInputError(f"{tok.where}: expected a word, got {tok.value!r}")
            if tok.value == "include":
                name = self._expect("string", None, 'a "file name" after include')
                self._include(name)
            elif tok.value == "define":
                new = self._expect("word", None, "the new type's name after define")
                base = self._expect("word", None, "the base type after define " + new.value)
                self._expect("punct", "(", f"'(' after define {new.value} {base.value}")
                props, children = self._body()
                self.world.defines[new.value] = _Define(base.value, props, children, tok.where)
            else:
                nxt = self._peek()
                if nxt is not None and nxt.kind == "punct" and nxt.value == "(":
                    self.pos += 1
                    props, children = self._body()
                    self.world.models.append(StageModel(tok.value, props, children, tok.where))
                else:
                    self._value(tok)  # a global setting: read and ignored

    def _include(self, name: Token) -> None:
        candidates = [self.path.parent / name.value, self.world.main_dir / name.value]
        target = next((p for p in candidates if p.is_file()), None)
        if target is None:
            raise MbnInputError(f"{name.where}: include file {name.value!r} not found")
        resolved = target.resolve()
        if resolved in self.world.including:
            raise MbnInputError(f"{name.where}: include {name.value!r} includes itself")
        self.world.including.append(resolved)
        text = read_text(target)
        _Parser(tokenize(text, str(target)), target, self.world).parse_file()
        self.world.including.pop()

    def _value(self, key: Token) -> list[Value]:
        tok = self._next(f"a value for {key.value}")
        if tok.kind == "number":
            return [float(tok.value)]
        if tok.kind == "string":
            return [tok.value]
        if tok.kind == "punct" and tok.value == "[":
            out: list[Value] = []
            while True:
                item = self._next(f"']' closing the tuple of {key.value}")
                if item.kind == "punct" and item.value == "]":
                    return out
                if item.kind == "number":
                    out.append(float(item.value))
                elif item.kind in ("string", "word"):
                    out.append(item.value)
                else:
                    raise MbnInputError(
                        f"{item.where}: unexpected {item.value!r} in the tuple of {key.value}"
                    )
        raise MbnInputError(
            f'{tok.where}: expected a number, a "string" or a [tuple] after {key.value},'
            f" got {tok.value!r}"
        )

    def _body(self, depth: int = 1) -> tuple[Props, list[StageModel]]:
        props: Props = {}
        children: list[StageModel] = []
        while True:
            tok = self._next("')'")
            if tok.kind == "punct" and tok.value == ")":
                return props, children
            if tok.kind != "word":
                raise MbnInputError(
                    f"{tok.where}: expected a property name, a model or ')', got {tok.value!r}"
                )
            nxt = self._peek()
            if nxt is not None and nxt.kind == "punct" and nxt.value == "(":
                if depth >= MAX_NESTING:
                    raise MbnInputError(f"{tok.where}: models nested more than {MAX_NESTING} deep")
                self.pos += 1
                sub_props, sub_children = self._body(depth + 1)
                children.append(StageModel(tok.value, sub_props, sub_children, tok.where))
            else:
                props[tok.value] = (self._value(tok), tok.where)


# ---------------------------------------------------------------------------------------------
# interpretation


def _resolve(world: _World, model: StageModel) -> tuple[Props, bool]:
    """The model's properties after inheritance, and whether its type derives from ``position``."""
    chain: list[_Define] = []
    seen: set[str] = set()
    t = model.type
    is_position = False
    while t in world.defines:
        if t in seen:
            raise MbnInputError(f"{model.where}: the definition of type {t!r} is circular")
        seen.add(t)
        d = world.defines[t]
        chain.append(d)
        t = d.base
    if t == "position":
        is_position = True
    props: Props = {}
    for d in reversed(chain):
        props.update(d.props)
    props.update(model.props)
    return props, is_position


def _inherited_children(world: _World, model: StageModel) -> list[StageModel]:
    chain: list[_Define] = []
    t = model.type
    seen: set[str] = set()
    while t in world.defines and t not in seen:
        seen.add(t)
        chain.append(world.defines[t])
        t = world.defines[t].base
    out: list[StageModel] = []
    for d in reversed(chain):
        out.extend(d.children)
    out.extend(model.children)
    return out


def _numbers(props: Props, key: str, n_min: int, n: int) -> list[float]:
    values, where = props[key]
    if not n_min <= len(values) <= n:
        want = f"{n_min}" if n_min == n else f"{n_min} to {n}"
        raise MbnInputError(f"{where}: {key} needs {want} numbers, got {len(values)}")
    out: list[float] = []
    for v in values:
        if not isinstance(v, float) or not math.isfinite(v):
            raise MbnInputError(f"{where}: {key} must hold finite numbers, got {v!r}")
        out.append(v)
    return out + [0.0] * (n - len(out))


def _quarter_turns(a_deg: float, where: str, what: str) -> int:
    q = a_deg / 90.0
    k = round(q)
    if abs(q - k) > 1e-9:
        raise MbnInputError(
            f"{where}: {what} rotation {a_deg:g} deg is not a multiple of 90 degrees"
            " (only axis-aligned walls are supported)"
        )
    return k % 4


@dataclass(frozen=True)
class _Frame:
    """A rigid transform by a multiple of 90 degrees: ``p -> (x, y) + R(k 90 deg) p``."""

    x: float = 0.0
    y: float = 0.0
    k: int = 0

    def apply(self, px: float, py: float) -> tuple[float, float]:
        c, s = _COS_SIN[self.k]
        return self.x + c * px - s * py, self.y + s * px + c * py

    def compose(self, x: float, y: float, k: int) -> _Frame:
        wx, wy = self.apply(x, y)
        return _Frame(wx, wy, (self.k + k) % 4)


_COS_SIN = ((1, 0), (0, 1), (-1, 0), (0, -1))


Rect = tuple[float, float, float, float]


@dataclass
class _Collected:
    walls: list[Rect] = field(default_factory=list)
    starts: list[tuple[float, float, float]] = field(default_factory=list)
    start_labels: list[str] = field(default_factory=list)


def _rect(frame: _Frame, cx: float, cy: float, sx: float, sy: float) -> Rect:
    """World rectangle of a box ``sx x sy`` centred at ``(cx, cy)`` of ``frame``."""
    x, y = frame.apply(cx, cy)
    if frame.k % 2:
        sx, sy = sy, sx
    return (x - sx / 2, x + sx / 2, y - sy / 2, y + sy / 2)


#: The deepest nesting of models read (Stage worlds nest a few levels: a robot in a world).
MAX_NESTING = 64

#: The largest bitmap floorplan read (pixels): a small compressed file can decode to gigapixels;
#: Stage floorplans are a few thousand pixels a side.
MAX_BITMAP_PIXELS = 16_000_000


def bitmap_grey(path: str | os.PathLike[str], where: str = "bitmap") -> np.ndarray:
    """The grey levels ``(H, W)`` of an image, first row north, on a 0..255 scale (float64).

    The image is decoded by Pillow; grey is the mean of R, G and B (alpha ignored), so a grey
    image gives its own levels. 16-bit grey images are scaled to 0..255 (``v / 257``); 16-bit
    colour PNGs come as 8-bit RGB from Pillow; 1-bit images give 0 and 255. An image that cannot be
    read is an :class:`MbnInputError` starting with ``where``.
    """
    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings():  # Pillow warns of large images; the limit below is ours
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            image = Image.open(path)  # reads the header only
        with image:
            width, height = image.size
            if width * height > MAX_BITMAP_PIXELS:
                raise MbnInputError(
                    f"{where}: bitmap {str(path)!r} is {width} x {height} pixels, over the limit "
                    f"of {MAX_BITMAP_PIXELS // 1_000_000} M pixels (scale it down)"
                )
            if image.mode.startswith("I;16") or (image.mode == "I" and image.format == "PNG"):
                return np.asarray(image, dtype=np.float64) / 257.0
            rgb = np.asarray(image.convert("RGB"), dtype=np.uint16)
    except MbnInputError:
        raise
    except Image.DecompressionBombError:
        raise MbnInputError(
            f"{where}: bitmap {str(path)!r} decodes to more pixels than the limit of "
            f"{MAX_BITMAP_PIXELS // 1_000_000} M pixels (scale it down)"
        ) from None
    except UnidentifiedImageError:
        raise MbnInputError(
            f"{where}: cannot read bitmap {str(path)!r} (not an image file Pillow can read)"
        ) from None
    except (OSError, ValueError, SyntaxError) as exc:
        reason = " ".join(str(exc).split())
        raise MbnInputError(f"{where}: cannot read bitmap {str(path)!r} ({reason})") from None
    return rgb.sum(axis=-1, dtype=np.uint16) / 3.0


def _load_bitmap(path: Path, where: str) -> np.ndarray:
    """Obstacle mask ``(H, W)`` of an image, first row north: grey (:func:`bitmap_grey`) <= 127."""
    return bitmap_grey(path, where) <= 127.0


def _bitmap_walls(
    props: Props,
    model: StageModel,
    frame: _Frame,
    world: _World,
    extent: str,
) -> list[Rect]:
    values, bwhere = props["bitmap"]
    if len(values) != 1 or not isinstance(values[0], str) or not values[0]:
        raise MbnInputError(f'{bwhere}: bitmap needs a "file name"')
    name = values[0]
    prop_dir = Path(bwhere.rsplit(":", 1)[0]).parent
    candidates = [Path(name)] if Path(name).is_absolute() else []
    candidates += [prop_dir / name, world.main_dir / name]
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        raise MbnInputError(f"{bwhere}: bitmap file {name!r} not found")
    if "size" not in props:
        raise MbnInputError(f"{model.where}: a bitmap model needs a size [sx sy sz]")
    sx, sy, _ = _numbers(props, "size", 2, 3)
    if sx <= 0 or sy <= 0:
        raise MbnInputError(f"{props['size'][1]}: size must be > 0, got {sx:g} x {sy:g}")
    solid = _load_bitmap(path, bwhere)
    if not np.any(solid):
        return []
    if extent == "dark":
        rows = np.flatnonzero(solid.any(axis=1))
        cols = np.flatnonzero(solid.any(axis=0))
        solid = solid[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    h, w = solid.shape
    px, py = sx / w, sy / h
    # rectangles in the model frame (centred on the model's origin point)
    local = merge_cells(solid, px, py, origin=(-sx / 2, -sy / 2))
    if _flag(props, "boundary"):
        ex, ey = 0.01 * px, 0.01 * py
        hx, hy = sx / 2, sy / 2
        edges = [
            [-hx, -hx + ex, -hy, hy],
            [hx - ex, hx, -hy, hy],
            [-hx, hx, -hy, -hy + ey],
            [-hx, hx, hy - ey, hy],
        ]
        local = np.concatenate([local, np.array(edges)], axis=0)
    return [
        _rect(frame, float(x0 + x1) / 2, float(y0 + y1) / 2, float(x1 - x0), float(y1 - y0))
        for x0, x1, y0, y1 in local
    ]


def _flag(props: Props, key: str) -> bool:
    if key not in props:
        return False
    values, where = props[key]
    if len(values) != 1 or not isinstance(values[0], float):
        raise MbnInputError(f"{where}: {key} must be a number")
    return values[0] != 0.0


def _model_frame(props: Props, model: StageModel, parent: _Frame) -> tuple[_Frame, _Frame]:
    """The model's pose frame, and its body frame (pose then origin)."""
    x, y, _, a = _numbers(props, "pose", 2, 4) if "pose" in props else [0.0] * 4
    where = props["pose"][1] if "pose" in props else model.where
    pose = parent.compose(x, y, _quarter_turns(a, where, "pose"))
    if "origin" in props:
        ox, oy, _, oa = _numbers(props, "origin", 2, 4)
        body = pose.compose(ox, oy, _quarter_turns(oa, props["origin"][1], "origin"))
    else:
        body = pose
    return pose, body


def _walk(
    world: _World,
    model: StageModel,
    parent: _Frame,
    out: _Collected,
    extent: str,
) -> None:
    props, is_position = _resolve(world, model)
    if model.type == "window":
        return
    if "bitmap" in props:
        _, body = _model_frame(props, model, parent)
        out.walls.extend(_bitmap_walls(props, model, body, world, extent))
    elif is_position:
        x, y, _, a = _numbers(props, "pose", 2, 4) if "pose" in props else [0.0] * 4
        wx, wy = parent.apply(x, y)
        heading = math.radians(a) + parent.k * math.pi / 2
        theta = math.atan2(math.sin(heading), math.cos(heading))
        name = props["name"][0][0] if "name" in props and props["name"][0] else model.type
        out.starts.append((wx, wy, theta))
        out.start_labels.append(f"{model.where}: robot {str(name)!r} (start #{len(out.starts)})")
        return  # a robot's children are its sensors and body parts
    elif "size" in props and "pose" in props and not _obstacle_free(props):
        _, body = _model_frame(props, model, parent)
        sx, sy, _ = _numbers(props, "size", 2, 3)
        if sx <= 0 or sy <= 0:
            raise MbnInputError(f"{props['size'][1]}: size must be > 0, got {sx:g} x {sy:g}")
        out.walls.append(_rect(body, 0.0, 0.0, sx, sy))
    pose, _ = _model_frame(props, model, parent)
    for child in _inherited_children(world, model):
        if child.type in ("block", "sensor"):
            continue
        _walk(world, child, pose, out, extent)


def _obstacle_free(props: Props) -> bool:
    return "obstacle_return" in props and not _flag(props, "obstacle_return")


def parse_stage_world(
    text: str,
    path: str | os.PathLike[str] = "<world>",
    *,
    name: str | None = None,
    bitmap_extent: Literal["dark", "image"] = "dark",
) -> Maze:
    """Parse world-file ``text`` (includes and bitmaps are found relative to ``path``) into a
    validated :class:`Maze`; see the module docstring for the rules."""
    if bitmap_extent not in ("dark", "image"):
        raise MbnInputError(f"bitmap_extent must be 'dark' or 'image', got {bitmap_extent!r}")
    p = Path(path)
    world = _World(main_dir=p.parent)
    world.including.append(p.resolve())
    _Parser(tokenize(text, str(p)), p, world).parse_file()
    out = _Collected()
    for model in world.models:
        _walk(world, model, _Frame(), out, bitmap_extent)
    if not out.walls:
        raise MbnInputError(f"{p}: the world has no walls (no model with size and pose, no bitmap)")
    walls = np.round(np.array(out.walls, dtype=np.float64).reshape(-1, 4), 9)
    starts = np.array(out.starts, dtype=np.float64).reshape(-1, 3)
    starts[:, :2] = np.round(starts[:, :2], 9)
    xs = [walls[:, 0].min(), walls[:, 1].max(), *starts[:, 0]]
    ys = [walls[:, 2].min(), walls[:, 3].max(), *starts[:, 1]]
    maze = Maze(
        name=name if name is not None else p.stem,
        walls=walls,
        bounds=(float(min(xs)), float(max(xs)), float(min(ys)), float(max(ys))),
        outside_is_wall=False,
        starts=starts,
        source=str(p),
    )
    validate_maze(maze, str(p), start_labels=out.start_labels)
    return maze


def read_stage_world(
    path: str | os.PathLike[str],
    *,
    bitmap_extent: Literal["dark", "image"] = "dark",
) -> Maze:
    """Read a Player/Stage ``.world`` file (see the module docstring)."""
    text = read_text(path)
    return parse_stage_world(text, path, name=Path(path).stem, bitmap_extent=bitmap_extent)

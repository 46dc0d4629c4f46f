"""Posts: a :class:`~ftrac_design.machining.toolpath.Program` as RS-274 text.

A post is one row of :data:`POSTS`. ``linuxcnc`` (the default) writes LinuxCNC's RS-274
dialect; ``fanuc`` a Fanuc-style program (``O`` number, ``N`` sequence numbers, upper-case
comments, two-digit tool and offset numbers, ``M30``, and ``M10``/``M11`` to clamp and
unclamp a braked A axis around the fixed-A cuts). Both write millimetres (G21), absolute
coordinates (G90), arc centres relative to the start (I, J), four decimals on every axis
(0.1 µm, 0.0001°) and inverse-time feeds (G93) on every move that turns A.
"""

from __future__ import annotations

from dataclasses import dataclass

from .toolpath import Clamp, Comment, Move, Program, Spindle, ToolChange


@dataclass(frozen=True)
class Post:
    """How one control wants its program written."""

    name: str
    description: str
    suffix: str
    program_number: int | None
    line_numbers: bool
    upper_comments: bool
    two_digit_tools: bool
    clamp: tuple[str, str] | None  # (clamp, unclamp) M-codes of a braked A axis
    end: str
    preamble: str


POSTS: dict[str, Post] = {
    "linuxcnc": Post(
        "linuxcnc",
        "LinuxCNC (RS-274/NGC)",
        ".ngc",
        None,
        False,
        False,
        False,
        None,
        "M2",
        "G21 G90 G91.1 G94 G17 G40 G49 G80 G54",
    ),
    "fanuc": Post(
        "fanuc",
        "Fanuc-style (O number, N numbers, M10/M11 A brake, M30)",
        ".nc",
        1000,
        True,
        True,
        True,
        ("M10", "M11"),
        "M30",
        "G21 G90 G94 G17 G40 G49 G80 G54",
    ),
}

#: default post
DEFAULT_POST = "linuxcnc"

AXES = "XYZA"


def _num(v: float) -> str:
    s = f"{v:.4f}"
    return "0.0000" if s == "-0.0000" else s


def _clean(text: str, upper: bool) -> str:
    t = text.replace("(", "[").replace(")", "]")
    return t.upper() if upper else t


def emit(program: Program, post: str = DEFAULT_POST, header: list[str] | None = None) -> str:
    """The program as RS-274 text.

    Parameters
    ----------
    program : Program
        Blocks from :func:`~ftrac_design.machining.toolpath.plan_program` (machine X, Y, Z mm, A deg).
    post : str
        A key of :data:`POSTS`.
    header : list of str, optional
        Comment lines written after the program start.

    Returns
    -------
    str
        The program, one block per line, ending in a newline.
    """
    if post not in POSTS:
        raise ValueError(f"unknown post {post!r}; expected one of {', '.join(POSTS)}")
    p = POSTS[post]
    w = _Writer(p)
    w.out.append("%")
    if p.program_number is not None:
        w.out.append(f"O{p.program_number} ({_clean(program.title, True)[:40]})")
    for h in header or []:
        w.comment(h)
    w.line(p.preamble)
    for b in program.blocks:
        if isinstance(b, Comment):
            w.comment(b.text)
        elif isinstance(b, ToolChange):
            w.tool_change(b.tool, program.safe_z)
        elif isinstance(b, Spindle):
            w.line(f"S{b.rpm:.0f} M3" if b.rpm > 0 else "M5")
        elif isinstance(b, Clamp):
            if p.clamp is not None and b.on != w.clamped:
                w.line(p.clamp[0] if b.on else p.clamp[1])
            w.clamped = b.on
        elif isinstance(b, Move):
            w.move(b)
    w.line("M5")
    w.line(p.end)
    w.out.append("%")
    return "\n".join(w.out) + "\n"


class _Writer:
    """The program's lines as one post writes them, and the modal state they leave: the last
    value written on each axis (as text), the feed mode and rate, the A-axis clamp."""

    def __init__(self, post: Post):
        self.p = post
        self.out: list[str] = []
        self.n = 0
        self.last: list[str | None] = [None, None, None, None]
        self.mode, self.feed, self.clamped = "G94", None, False

    def line(self, text: str) -> None:
        if self.p.line_numbers and not text.startswith("("):
            self.n = self.n % 99999 + 1  # five-digit sequence numbers, wrapping as Fanuc controls allow
            text = f"N{self.n} {text}"
        self.out.append(text)

    def comment(self, text: str) -> None:
        self.out.append(f"({_clean(text, self.p.upper_comments)})")

    def tool_change(self, tl, safe_z: float) -> None:
        t = f"{tl.number:02d}" if self.p.two_digit_tools else str(tl.number)
        self.comment(
            f"T{tl.number}: {tl.diameter:g} mm flat end mill, {tl.rpm:g} rpm, feed {tl.feed:g} mm/min, "
            f"plunge {tl.plunge_feed:g} mm/min"
        )
        self.line(f"T{t} M6" if not self.p.two_digit_tools else f"T{t} M06")
        self.line(f"G0 G43 H{t} Z{_num(safe_z)}")
        self.last[2] = _num(safe_z)

    def move(self, b: Move) -> None:
        words = []
        if b.kind == "rapid":
            new_mode = self.mode
        else:
            new_mode = "G93" if b.feed_mode == "inverse_time" else "G94"
        if new_mode != self.mode:
            words.append(new_mode)
            self.mode, self.feed = new_mode, None
        words.append({"rapid": "G0", "feed": "G1", "arc": "G3" if b.ccw else "G2"}[b.kind])
        start = [float(v) if v is not None else 0.0 for v in self.last]
        for i, ax in enumerate(AXES):
            v = _num(b.end[i])
            if v != self.last[i] or (b.kind == "arc" and i < 2):
                words.append(f"{ax}{v}")
                self.last[i] = v
        if b.kind == "arc":
            words.append(f"I{_num(b.centre[0] - start[0])} J{_num(b.centre[1] - start[1])}")
        if b.kind != "rapid":
            f = f"{b.f:.3f}" if self.mode == "G93" else f"{b.f:.1f}"
            if self.mode == "G93" or f != self.feed:
                words.append(f"F{f}")
                self.feed = f
        self.line(" ".join(words))

"""Draws the FMU icons: `fmus/<dir>/icon.svg` and `icon.png` (128 × 128 pixels), which the
packager puts into every FMI 3.0 archive as `terminalsAndIcons/icon.svg` and `icon.png`
(FMI 3.0.2 §2.4.9.1.3; `master/cli/src/fmi3_extras`), and the terminal icons all FMUs share,
`fmus/export/icons/input` and `output` (32 × 32 pixels: a filled and an open triangle
pointing with the signal, as block diagrams draw inputs and outputs).

Each symbol is one list of shapes in a 100 × 100 box (y downwards), written twice from the
same list: as SVG text by hand (a few hundred bytes) and as a PNG through Pillow (drawn at
four times the size and reduced, for smooth edges). The symbols say what the model is: the
crane (rail, cart, rope, load), the generator (a sine wave in a machine circle), the filter
(a low-pass magnitude curve), the estimators (a bell curve under a hat: x̂; the robust ones
with an outlier, the dual ones with two estimates, the RLS a line fitted through samples,
the distributed observer two estimators that exchange; the plant estimator the robust one
beside the step response of the plant it carries), the controllers (a feedback loop
through a gain; the adaptive one crossed by the adaptation arrow), the sensor (a dial),
the signal source (a staircase in a source circle), the plant (a step response), the table
(a grid).

    .venv/bin/python scripts/draw-icons.py          # rewrites every icon
    .venv/bin/python scripts/draw-icons.py --check  # fails when a committed icon differs
"""

from __future__ import annotations

import argparse
import io
import math
import sys
from pathlib import Path

from PIL import Image, ImageDraw

REPO = Path(__file__).resolve().parents[1]
SIZE = 128
TERMINAL_SIZE = 32
OVERSAMPLE = 4
INK = "#1f3b57"
ACCENT = "#c8553d"
PAPER = "#f4f7fb"

# A shape: (kind, points or geometry, stroke, width, fill).
Shape = tuple


def frame() -> list[Shape]:
    return [("rect", (4, 4, 96, 96, 10), INK, 3, PAPER)]


def curve(f, x0: float, x1: float, n: int = 24) -> list[tuple[float, float]]:
    return [(x0 + (x1 - x0) * k / n, f(x0 + (x1 - x0) * k / n)) for k in range(n + 1)]


def bell(centre: float, width: float, base: float, height: float) -> list[tuple[float, float]]:
    return curve(lambda x: base - height * math.exp(-((x - centre) / width) ** 2), centre - 2.6 * width,
                 centre + 2.6 * width)


def hat(x: float, y: float, half: float = 9) -> Shape:
    return ("line", [(x - half, y + 6), (x, y), (x + half, y + 6)], ACCENT, 4, None)


def crane() -> list[Shape]:
    return frame() + [
        ("line", [(12, 26), (88, 26)], INK, 4, None),  # rail
        ("rect", (34, 18, 32, 14, 3), INK, 3, "#9fb6cc"),  # cart
        ("circle", (40, 33, 4), INK, 2, PAPER), ("circle", (60, 33, 4), INK, 2, PAPER),
        ("line", [(50, 32), (64, 72)], INK, 3, None),  # rope, swung out
        ("circle", (66, 78, 8), INK, 3, ACCENT),  # load
        ("line", [(50, 40), (50, 84)], "#8a9bb0", 1.5, None),  # plumb line
    ]


def generator() -> list[Shape]:
    return frame() + [
        ("circle", (50, 50, 30), INK, 4, "#e3ebf3"),
        ("line", curve(lambda x: 50 - 12 * math.sin((x - 30) / 40 * 2 * math.pi), 30, 70), ACCENT, 4,
         None),
        ("line", [(8, 50), (20, 50)], INK, 3, None), ("line", [(80, 50), (92, 50)], INK, 3, None),
    ]


def low_pass() -> list[Shape]:
    return frame() + [
        ("line", [(16, 20), (16, 82), (86, 82)], INK, 3, None),  # axes
        ("line", curve(lambda x: 34 + 44 / (1 + math.exp(-(x - 58) / 6)), 16, 86), ACCENT, 4, None),
        ("line", [(58, 78), (58, 86)], INK, 2, None),  # corner frequency
    ]


def estimator(bells: int = 1, outlier: bool = False) -> list[Shape]:
    shapes = frame() + [("line", [(12, 80), (88, 80)], INK, 3, None)]
    centres = [50] if bells == 1 else [36, 62]
    for k, c in enumerate(centres):
        shapes.append(("line", bell(c, 10, 80, 40 - 8 * k), INK, 4, None))
        shapes.append(hat(c, 22 + 8 * k))
    if outlier:
        shapes.append(("circle", (82, 30, 5), ACCENT, 2, ACCENT))
    return shapes


def identification() -> list[Shape]:
    samples = [(20, 70), (30, 66), (38, 55), (48, 52), (58, 42), (68, 39), (78, 28)]
    return frame() + [
        ("line", [(14, 78), (86, 24)], ACCENT, 4, None),
        *[("circle", (x, y, 3.5), INK, 2, INK) for x, y in samples],
        hat(50, 14, 7),
    ]


def observers() -> list[Shape]:
    return frame() + [
        ("circle", (28, 60, 16), INK, 3, "#e3ebf3"), ("circle", (72, 60, 16), INK, 3, "#e3ebf3"),
        hat(28, 52, 8), hat(72, 52, 8),
        ("line", [(36, 36), (50, 26), (64, 36)], INK, 3, None),  # exchange of estimates
        ("line", [(58, 36), (64, 36), (63, 30)], INK, 3, None),
        ("line", [(42, 36), (36, 36), (37, 30)], INK, 3, None),
    ]


def controller(adaptive: bool = False) -> list[Shape]:
    shapes = frame() + [
        ("line", [(10, 40), (26, 40)], INK, 3, None),
        ("circle", (32, 40, 6), INK, 3, PAPER),  # summing junction
        ("line", [(38, 40), (46, 40)], INK, 3, None),
        ("poly", [(46, 26), (46, 54), (72, 40)], INK, 3, "#9fb6cc"),  # gain
        ("line", [(72, 40), (90, 40)], INK, 3, None),
        ("line", [(82, 40), (82, 74), (32, 74), (32, 46)], INK, 3, None),  # feedback
        ("line", [(28, 52), (32, 46), (36, 52)], INK, 3, None),
    ]
    if adaptive:
        shapes += [("line", [(40, 66), (80, 16)], ACCENT, 4, None),
                   ("line", [(70, 18), (80, 16), (78, 26)], ACCENT, 4, None)]
    return shapes


def sensor() -> list[Shape]:
    arc = [(50 + 34 * math.cos(a), 66 - 34 * math.sin(a))
           for a in [math.pi * k / 24 for k in range(25)]]
    ticks = []
    for k in range(7):
        a = math.pi * k / 6
        ticks.append(("line", [(50 + 28 * math.cos(a), 66 - 28 * math.sin(a)),
                               (50 + 34 * math.cos(a), 66 - 34 * math.sin(a))], INK, 2, None))
    return frame() + [("line", arc, INK, 4, None), *ticks,
                      ("line", [(50, 66), (70, 42)], ACCENT, 4, None),
                      ("circle", (50, 66, 5), INK, 2, INK), ("line", [(14, 80), (86, 80)], INK, 3, None)]


def source() -> list[Shape]:
    stairs = [(32, 62), (42, 62), (42, 50), (52, 50), (52, 38), (62, 38), (62, 56), (70, 56)]
    return frame() + [("circle", (46, 50, 28), INK, 4, "#e3ebf3"), ("line", stairs, ACCENT, 4, None),
                      ("line", [(74, 50), (92, 50)], INK, 3, None),
                      ("line", [(85, 44), (92, 50), (85, 56)], INK, 3, None)]


def plant() -> list[Shape]:
    step_response = curve(lambda x: 72 - 42 * (1 - math.exp(-(x - 20) / 9) * math.cos((x - 20) / 7)), 20, 86)
    return frame() + [("line", [(14, 20), (14, 80), (88, 80)], INK, 3, None),
                      ("line", [(14, 72), (20, 72), (20, 30), (88, 30)], "#8a9bb0", 2, None),
                      ("line", step_response, ACCENT, 4, None)]


def table() -> list[Shape]:
    shapes = frame() + [("rect", (16, 20, 68, 60, 2), INK, 3, PAPER),
                        ("rect", (16, 20, 68, 12, 2), INK, 3, "#9fb6cc")]
    for y in (44, 56, 68):
        shapes.append(("line", [(16, y), (84, y)], INK, 2, None))
    for x in (38, 61):
        shapes.append(("line", [(x, 20), (x, 80)], INK, 2, None))
    return shapes


def plant_estimator() -> list[Shape]:
    """The robust estimator (bell under a hat, an outlier) of a plant carried inside (the
    plant's step response in a box)."""
    response = curve(lambda x: 76 - 14 * (1 - math.exp(-(x - 64) / 5)), 64, 86, 12)
    return frame() + [
        ("line", [(10, 80), (58, 80)], INK, 3, None),
        ("line", bell(34, 8, 80, 36), INK, 4, None),
        hat(34, 26),
        ("circle", (52, 30, 5), ACCENT, 2, ACCENT),
        ("rect", (60, 52, 30, 30, 3), INK, 3, "#e3ebf3"),
        ("line", response, ACCENT, 3, None),
    ]


# fmus/<dir>/ → its symbol.
SYMBOLS = {
    "GantryCrane": crane,
    "WindGenerator": generator,
    "OpAmpFilter": low_pass,
    "KalmanFilter": estimator,
    "RobustKalmanFilter": lambda: estimator(outlier=True),
    "DualKalmanFilter": lambda: estimator(bells=2),
    "DkfRsKf": lambda: estimator(bells=2, outlier=True),
    "RecursiveLeastSquares": identification,
    "PlantEstimator": plant_estimator,
    "DistributedObserver": observers,
    "StateFeedback": controller,
    "AdaptiveStateFeedback": lambda: controller(adaptive=True),
    "Sensor": sensor,
    "SignalSource": source,
    "LinearSystem": plant,
    "TimeTable": table,
}


def terminal(fill: str) -> list[Shape]:
    return [("poly", [(12, 10), (90, 50), (12, 90)], INK, 8, fill)]


# fmus/export/icons/<name> → its symbol.
TERMINALS = {"input": lambda: terminal(INK), "output": lambda: terminal("#ffffff")}


def num(v: float) -> str:
    return f"{v:.2f}".rstrip("0").rstrip(".")


def svg(shapes: list[Shape], title: str, size: int) -> str:
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}" '
           f'viewBox="0 0 100 100"><title>{title}</title>']
    for kind, geometry, stroke, width, fill in shapes:
        paint = (f' fill="{fill or "none"}" stroke="{stroke}" stroke-width="{num(width)}" '
                 'stroke-linecap="round" stroke-linejoin="round"')
        if kind == "rect":
            x, y, w, h, r = geometry
            out.append(f'<rect x="{num(x)}" y="{num(y)}" width="{num(w)}" height="{num(h)}" '
                       f'rx="{num(r)}"{paint}/>')
        elif kind == "circle":
            cx, cy, r = geometry
            out.append(f'<circle cx="{num(cx)}" cy="{num(cy)}" r="{num(r)}"{paint}/>')
        else:
            points = " ".join(f"{num(x)},{num(y)}" for x, y in geometry)
            element = "polygon" if kind == "poly" else "polyline"
            out.append(f'<{element} points="{points}"{paint}/>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def png(shapes: list[Shape], size: int) -> bytes:
    big = size * OVERSAMPLE
    scale = big / 100
    image = Image.new("RGBA", (big, big), (0, 0, 0, 0))
    draw = ImageDraw.Draw(image)
    for kind, geometry, stroke, width, fill in shapes:
        w = max(1, round(width * scale))
        if kind == "rect":
            x, y, wd, h, r = geometry
            draw.rounded_rectangle([x * scale, y * scale, (x + wd) * scale, (y + h) * scale],
                                   radius=r * scale, fill=fill, outline=stroke, width=w)
        elif kind == "circle":
            cx, cy, r = geometry
            draw.ellipse([(cx - r) * scale, (cy - r) * scale, (cx + r) * scale, (cy + r) * scale],
                         fill=fill, outline=stroke, width=w)
        else:
            points = [(x * scale, y * scale) for x, y in geometry]
            if kind == "poly":
                draw.polygon(points, fill=fill)
                points = points + points[:1]
            draw.line(points, fill=stroke, width=w, joint="curve")
            for x, y in (points[0], points[-1]):  # round caps
                draw.ellipse([x - w / 2, y - w / 2, x + w / 2, y + w / 2], fill=stroke)
    small = image.resize((size, size), Image.Resampling.LANCZOS)
    buffer = io.BytesIO()
    small.save(buffer, format="PNG", optimize=True)
    return buffer.getvalue()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="compare with the committed icons instead of writing them")
    args = parser.parse_args()
    stale = []
    drawings = [(REPO / "fmus" / folder, "icon", folder, draw, SIZE)
                for folder, draw in SYMBOLS.items()]
    shared = REPO / "fmus" / "export" / "icons"
    drawings += [(shared, name, f"{name} terminal", draw, TERMINAL_SIZE)
                 for name, draw in TERMINALS.items()]
    for folder, base, title, draw, size in drawings:
        shapes = draw()
        files = {f"{base}.svg": svg(shapes, title, size).encode(), f"{base}.png": png(shapes, size)}
        folder.mkdir(exist_ok=True)
        for name, data in files.items():
            path = folder / name
            if args.check:
                if not path.is_file() or path.read_bytes() != data:
                    stale.append(str(path.relative_to(REPO)))
            else:
                path.write_bytes(data)
    if stale:
        print("draw-icons: stale icons (run scripts/draw-icons.py):", *stale, sep="\n  ",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

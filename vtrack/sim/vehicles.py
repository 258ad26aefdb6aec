"""The vehicle mix of the perspective scenes: classes, sizes, speeds, colours and 3-D bodies.

Every vehicle is drawn from the seed: its class (motorcycle, car, van, truck), its body style
(saloon, hatchback, SUV, estate; rigid or articulated truck), its dimensions and colours.
A vehicle is one or two rigid units (a tractor and its semitrailer) that follow its path: a
unit spans the arc lengths [s - rear, s - front] behind the vehicle's front s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtrack.sim.shapes import Mesh, MeshBuilder


@dataclass(frozen=True)
class Kind:
    """A vehicle class: share of the mix, length/width ranges (m), desired speed range as
    a fraction of the road's speed limit, maximum acceleration (m/s^2)."""

    share: float
    length: tuple[float, float]
    width: tuple[float, float]
    speed: tuple[float, float]
    a_max: float


KINDS = {
    "motorcycle": Kind(0.08, (1.9, 2.3), (0.75, 0.9), (0.9, 1.15), 2.6),
    "car": Kind(0.56, (3.7, 5.0), (1.68, 1.95), (0.85, 1.1), 1.7),
    "van": Kind(0.18, (4.8, 6.6), (1.9, 2.2), (0.8, 1.0), 1.3),
    "truck": Kind(0.18, (7.0, 11.5), (2.4, 2.55), (0.7, 0.88), 0.8),
}
ARTICULATED_M = (15.2, 16.5)        # overall length of a tractor + semitrailer

# Body colours (BGR) with the weights of a real fleet: white, black, greys and silver lead.
CAR_COLOURS = [((232, 232, 230), 22), ((30, 29, 28), 16), ((128, 128, 124), 12),
               ((178, 178, 172), 13), ((70, 72, 74), 8), ((150, 62, 25), 7),
               ((35, 35, 165), 7), ((45, 80, 40), 3), ((105, 150, 175), 3),
               ((40, 150, 220), 2), ((80, 40, 20), 4), ((60, 60, 110), 3)]
CARGO_COLOURS = [((236, 236, 234), 40), ((190, 190, 186), 15), ((150, 90, 40), 10),
                 ((40, 40, 170), 10), ((45, 110, 50), 6), ((50, 160, 210), 6),
                 ((90, 90, 92), 8), ((30, 90, 200), 5)]
GLASS = (58, 50, 44)
TYRE = (28, 28, 30)
RIM = (120, 120, 122)
UNDER = (22, 22, 24)
HEADLAMP = (205, 220, 228)
TAILLAMP = (40, 40, 175)
DARK = (45, 45, 48)


@dataclass(frozen=True)
class Vehicle:
    """A drawn vehicle: class, overall size (m), its units' arc offsets and its body."""

    kind: str
    length: float
    width: float
    height: float
    units: np.ndarray          # (U, 2): (front, rear) offsets behind the vehicle's front
    mesh: Mesh
    speed_factor: float        # desired speed / the road's speed limit
    a_max: float


def _pick(rng: np.random.Generator, table: list) -> tuple[float, float, float]:
    """A colour from a weighted table, jittered a little."""
    weights = np.array([w for _, w in table], float)
    colour = np.array(table[rng.choice(len(table), p=weights / weights.sum())][0], float)
    return tuple(np.clip(colour * rng.uniform(0.92, 1.06) + rng.uniform(-6, 6, 3), 0, 255))


def draw_kind(rng: np.random.Generator, mix: bool, shares: dict[str, float] | None = None) -> str:
    """A class from the mix (cars only without `mix`); `shares` overrides KINDS' shares."""
    if not mix:
        return "car"
    names = list(KINDS)
    p = np.array([(shares or {}).get(n, KINDS[n].share) for n in names])
    return names[rng.choice(len(names), p=p / p.sum())]


def draw_vehicle(rng: np.random.Generator, kind: str, articulated_share: float = 0.4) -> Vehicle:
    """A vehicle of class `kind` with dimensions, style and colours drawn from rng."""
    k = KINDS[kind]
    speed = rng.uniform(*k.speed)
    width = rng.uniform(*k.width)
    if kind == "truck" and rng.random() < articulated_share:
        length = rng.uniform(*ARTICULATED_M)
        mesh, units, height = _articulated(rng, length, width)
    else:
        length = rng.uniform(*k.length)
        mesh, height = {"motorcycle": _motorcycle, "car": _car, "van": _van,
                        "truck": _truck}[kind](rng, length, width)
        units = np.array([[0.0, length]])
    return Vehicle(kind, length, width, height, units, mesh, speed, k.a_max)


def _wheels(b: MeshBuilder, faces: dict[str, int], axles: list[float], x: tuple[float, float],
            z: tuple[float, float], radius: float) -> None:
    """Tyres with rims on both side faces of a block spanning x and z, at axle positions."""
    span, height = x[1] - x[0], z[1] - z[0]
    for side in ("right", "left"):
        for ax in axles:
            u = ((ax - radius - x[0]) / span, (ax + radius - x[0]) / span)
            v = ((0 - z[0]) / height, (2 * radius - z[0]) / height)
            b.decal(faces[side], u, v, TYRE, round_=True)
            du, dv = 0.45 * (u[1] - u[0]), 0.45 * (v[1] - v[0])
            mu, mv = 0.5 * (u[0] + u[1]), 0.5 * (v[0] + v[1])
            b.decal(faces[side], (mu - du / 2, mu + du / 2), (mv - dv / 2, mv + dv / 2), RIM,
                    round_=True)


def _lamps(b: MeshBuilder, face: int, v: tuple[float, float], colour: tuple, inset: float,
           size: float) -> None:
    """A pair of lamps at both ends of a front or back face."""
    b.decal(face, (inset, inset + size), v, colour, glow=True)
    b.decal(face, (1 - inset - size, 1 - inset), v, colour, glow=True)


def _car(rng: np.random.Generator, length: float, width: float) -> tuple[Mesh, float]:
    """Saloon, hatchback, SUV or estate: a body block and a tapered glass cabin."""
    style = rng.choice(["saloon", "hatch", "suv", "estate"], p=[0.35, 0.3, 0.22, 0.13])
    cabin, roof, height, belt = {
        "saloon": ((0.22, 0.75), (0.32, 0.61), rng.uniform(1.40, 1.50), rng.uniform(0.74, 0.84)),
        "hatch": ((0.03, 0.72), (0.07, 0.58), rng.uniform(1.45, 1.56), rng.uniform(0.78, 0.88)),
        "suv": ((0.04, 0.76), (0.06, 0.66), rng.uniform(1.62, 1.80), rng.uniform(0.92, 1.02)),
        "estate": ((0.03, 0.74), (0.05, 0.63), rng.uniform(1.44, 1.52), rng.uniform(0.76, 0.84)),
    }[str(style)]
    colour = _pick(rng, CAR_COLOURS)
    b = MeshBuilder()
    hw, L = width / 2, length
    body = b.block((0, L), hw, (0, belt), colour, top_x=(0.02 * L, 0.98 * L),
                   top_half_width=hw - 0.03)
    cab = b.block((cabin[0] * L, cabin[1] * L), hw - 0.05, (belt, height), colour,
                  top_x=(roof[0] * L, roof[1] * L), top_half_width=hw - 0.2)
    under = 0.16 / belt
    for name in ("right", "left", "front", "back"):
        b.decal(body[name], (0, 1), (0, under), UNDER)
    _wheels(b, body, [0.19 * L, 0.81 * L], (0, L), (0, belt), rng.uniform(0.30, 0.36))
    _lamps(b, body["front"], (0.62, 0.88), HEADLAMP, 0.04, 0.2)
    b.decal(body["front"], (0.3, 0.7), (0.4, 0.72), DARK)                       # grille
    b.decal(body["front"], (0.38, 0.62), (0.2, 0.34), (215, 215, 215))          # plate
    _lamps(b, body["back"], (0.6, 0.86), TAILLAMP, 0.03, 0.2)
    b.decal(body["back"], (0.38, 0.62), (0.3, 0.46), (215, 215, 215))
    b.decal(cab["front"], (0.05, 0.95), (0.06, 0.94), GLASS)
    b.decal(cab["back"], (0.08, 0.92), (0.12, 0.9), GLASS)
    for side in ("right", "left"):
        b.decal(cab[side], (0.07, 0.48), (0.12, 0.88), GLASS)
        b.decal(cab[side], (0.52, 0.93), (0.12, 0.88), GLASS)
    return b.build(), height


def _van(rng: np.random.Generator, length: float, width: float) -> tuple[Mesh, float]:
    """A panel van: a low body and a tall box with a raked windscreen."""
    height = rng.uniform(1.95, 2.75)
    colour = _pick(rng, CAR_COLOURS if rng.random() < 0.4 else CARGO_COLOURS)
    b = MeshBuilder()
    hw, L = width / 2, length
    body = b.block((0, L), hw, (0, 1.0), colour)
    box = b.block((0, 0.86 * L), hw - 0.02, (1.0, height), colour, top_x=(0, 0.79 * L),
                  top_half_width=hw - 0.07)
    for name in ("right", "left", "front", "back"):
        b.decal(body[name], (0, 1), (0, 0.17), UNDER)
    _wheels(b, body, [0.18 * L, 0.83 * L], (0, L), (0, 1.0), 0.34)
    _lamps(b, body["front"], (0.55, 0.85), HEADLAMP, 0.04, 0.18)
    b.decal(body["front"], (0.28, 0.72), (0.35, 0.75), DARK)
    _lamps(b, body["back"], (0.45, 0.9), TAILLAMP, 0.02, 0.1)
    b.decal(box["back"], (0.495, 0.505), (0.0, 0.95), DARK)                     # rear doors
    b.decal(box["front"], (0.05, 0.95), (0.05, 0.8), GLASS)
    for side in ("right", "left"):
        b.decal(box[side], (0.8, 0.98), (0.3, 0.85), GLASS)
    return b.build(), height


def _cab(b: MeshBuilder, x: tuple[float, float], hw: float, top: float, colour: tuple,
         unit: int) -> dict[str, int]:
    """A truck cab: flat front with windscreen, grille, lamps and side windows."""
    cab = b.block(x, hw, (0.45, top), colour, unit=unit, top_x=(x[0], x[1] - 0.12),
                  top_half_width=hw - 0.05)
    front = cab["front"]
    b.decal(front, (0.06, 0.94), (0.58, 0.9), GLASS)
    b.decal(front, (0.2, 0.8), (0.12, 0.42), DARK)
    _lamps(b, front, (0.05, 0.13), HEADLAMP, 0.03, 0.16)
    for side in ("right", "left"):
        b.decal(cab[side], (0.55, 0.95), (0.58, 0.88), GLASS)
    return cab


def _truck(rng: np.random.Generator, length: float, width: float) -> tuple[Mesh, float]:
    """A rigid truck: cab, chassis and cargo box."""
    height = rng.uniform(3.2, 3.95)
    b = MeshBuilder()
    hw, L = width / 2, length
    cab_x = (L - 2.3, L)
    cab = _cab(b, cab_x, hw, rng.uniform(2.85, 3.2), _pick(rng, CARGO_COLOURS), 0)
    chassis = b.block((0.3, L - 2.3), hw - 0.12, (0.3, 1.05), DARK)
    b.block((0, L - 2.45), hw, (1.05, height), _pick(rng, CARGO_COLOURS))
    _wheels(b, chassis, [1.2 + 0.3, 2.6 + 0.3], (0.3, L - 2.3), (0.3, 1.05), 0.5)
    _wheels(b, cab, [L - 1.2], cab_x, (0.45, 3.0), 0.5)
    _lamps(b, chassis["back"], (0.2, 0.7), TAILLAMP, 0.02, 0.12)
    return b.build(), height


def _articulated(rng: np.random.Generator, length: float,
                 width: float) -> tuple[Mesh, np.ndarray, float]:
    """A tractor (unit 0) and a box semitrailer (unit 1) coupled behind the cab."""
    b = MeshBuilder()
    hw = width / 2
    tractor, trailer_front = 6.0, 2.7
    trailer = length - trailer_front
    cab = _cab(b, (3.7, tractor), hw, rng.uniform(3.2, 3.6), _pick(rng, CARGO_COLOURS), 0)
    frame = b.block((0, 3.7), hw - 0.15, (0.45, 1.15), DARK)
    _wheels(b, frame, [0.9, 2.3], (0, 3.7), (0.45, 1.15), 0.5)
    _wheels(b, cab, [tractor - 1.2], (3.7, tractor), (0.45, 3.2), 0.5)
    height = rng.uniform(3.85, 4.0)
    box = b.block((0, trailer), hw, (1.15, height), _pick(rng, CARGO_COLOURS), unit=1)
    skirt = b.block((0.4, 4.6), hw - 0.12, (0.35, 1.15), DARK, unit=1)
    _wheels(b, skirt, [1.2, 2.5, 3.8], (0.4, 4.6), (0.35, 1.15), 0.5)
    _lamps(b, skirt["back"], (0.3, 0.8), TAILLAMP, 0.02, 0.12)
    if rng.random() < 0.5:                                                     # livery band
        for side in ("right", "left"):
            b.decal(box[side], (0.05, 0.95), (0.35, 0.55), _pick(rng, CARGO_COLOURS))
    units = np.array([[0.0, tractor], [trailer_front, length]])
    return b.build(), units, height


def _motorcycle(rng: np.random.Generator, length: float, width: float) -> tuple[Mesh, float]:
    """A motorcycle with its rider: a narrow bike, a torso and a helmet."""
    b = MeshBuilder()
    L = length
    bike = b.block((0, L), 0.17, (0.0, 0.78), _pick(rng, CAR_COLOURS))
    _wheels(b, bike, [0.17 * L, 0.83 * L], (0, L), (0.0, 0.78), 0.31)
    b.decal(bike["front"], (0.2, 0.8), (0.65, 0.9), HEADLAMP, glow=True)
    b.decal(bike["back"], (0.25, 0.75), (0.65, 0.85), TAILLAMP, glow=True)
    jacket = _pick(rng, CAR_COLOURS)
    b.block((0.3 * L, 0.6 * L), width / 2 - 0.2, (0.78, 1.38), jacket,
            top_x=(0.36 * L, 0.58 * L), top_half_width=width / 2 - 0.25)
    height = rng.uniform(1.55, 1.68)
    b.block((0.42 * L, 0.58 * L), 0.13, (1.38, height), _pick(rng, CAR_COLOURS))
    b.block((0.7 * L, 0.76 * L), width / 2, (0.95, 1.02), DARK)                 # handlebar
    return b.build(), height

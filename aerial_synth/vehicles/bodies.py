"""More passenger-car body types and the size range of every small-vehicle segment.

Cars are the majority of vehicles in every real aerial dataset, and a detector that saw six
car shapes lags on the real spread (issue 29: small-vehicle AP50 0.65 against 0.87 for
large). This module adds the body types the thesis's nine models lacked, as side-profile
parameters of the procedural car builder in :mod:`.meshes` (``_car``): a city car, an
estate, a minivan, a panel van and a minibus. It is pure data (no import of the mesh
code), so :mod:`.model` and :mod:`.catalog` can read it too.

Profile fields (lengths as fractions of the model's length L or height H, as ``_car``):

    bonnet          : nose to the windscreen base, x L
    ws_run          : horizontal run of the windscreen, metres
    rw_top, rw_base : rear window's upper and lower edge from the tail, x L
    belt, nose_top, tail_top : beltline, bonnet front and tail heights, x H
    wheel_r, clear  : tyre radius and body underside, metres
    tumble          : inward lean of the side glass at the roof, metres
    rails           : longitudinal roof rails
    glass_sides     : side windows (False: a panel van's painted load area)
    option_rates    : trim options drawn per vehicle (sunroof, roof_rack, roof_box)

Segment sizes (:data:`SEGMENT_SIZES_M`): bounding boxes (length, width without mirrors,
height) of current models of each segment, from the makers' published dimensions; the
catalog's models must lie inside their segment's range (tests/vehicles/test_bodies.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["CarProfile", "CAR_PROFILES", "SEGMENT_SIZES_M", "BODY_SEGMENT", "car_kwargs"]


@dataclass(frozen=True)
class CarProfile:
    bonnet: float
    ws_run: float
    rw_top: float
    rw_base: float
    belt: float
    nose_top: float
    tail_top: float
    wheel_r: float
    clear: float = 0.16
    tumble: float = 0.16
    rails: bool = False
    glass_sides: bool = True
    option_rates: dict = field(default_factory=dict)


#: body type -> profile (new body types; the thesis's are built in .meshes)
CAR_PROFILES: dict[str, CarProfile] = {
    # A-segment city car: short bonnet, steep windscreen, near-vertical hatch
    "compact": CarProfile(bonnet=0.20, ws_run=0.72, rw_top=0.08, rw_base=0.02, belt=0.58,
                          nose_top=0.52, tail_top=0.60, wheel_r=0.29, clear=0.15, tumble=0.15,
                          option_rates={"sunroof": 0.12, "roof_rack": 0.02}),
    # estate (station wagon): saloon front, roof carried to the tail, roof rails
    "estate": CarProfile(bonnet=0.28, ws_run=0.80, rw_top=0.06, rw_base=0.02, belt=0.60,
                         nose_top=0.50, tail_top=0.62, wheel_r=0.32, tumble=0.16, rails=True,
                         option_rates={"sunroof": 0.25, "roof_rack": 0.05, "roof_box": 0.06}),
    # minivan / MPV: one-box profile, long raked windscreen, sliding doors
    "mpv": CarProfile(bonnet=0.17, ws_run=0.95, rw_top=0.05, rw_base=0.015, belt=0.52,
                      nose_top=0.50, tail_top=0.56, wheel_r=0.34, clear=0.17, tumble=0.14, rails=True,
                      option_rates={"sunroof": 0.20, "roof_box": 0.04}),
    # panel van (Caddy to Transit Custom): painted load area, glass only in the cab
    "van": CarProfile(bonnet=0.15, ws_run=0.85, rw_top=0.025, rw_base=0.01, belt=0.50,
                      nose_top=0.48, tail_top=0.52, wheel_r=0.33, clear=0.18, tumble=0.06,
                      glass_sides=False, option_rates={"roof_rack": 0.25}),
    # minibus (8-9 seat Kombi): the van's shape with windows all round
    "minibus": CarProfile(bonnet=0.15, ws_run=0.85, rw_top=0.025, rw_base=0.01, belt=0.50,
                          nose_top=0.48, tail_top=0.52, wheel_r=0.33, clear=0.18, tumble=0.10,
                          option_rates={"roof_rack": 0.05}),
}

#: body type -> market segment (the size ranges below)
BODY_SEGMENT: dict[str, str] = {
    "compact": "compact", "hatchback": "hatchback", "sedan": "sedan", "sport": "sport",
    "estate": "estate", "suv": "suv", "pickup": "pickup", "mpv": "van", "van": "van",
    "delivery_van": "van", "minibus": "minibus",
}

#: segment -> ((length lo, hi), (width lo, hi), (height lo, hi)) metres. Examples (L x W x H):
#:   compact   Toyota Aygo 3.47 x 1.62 x 1.46; VW up! 3.60 x 1.65 x 1.50; Fiat 500 3.57 x 1.63 x 1.49;
#:             Renault Twingo 3.62 x 1.65 x 1.55
#:   hatchback VW Polo 4.05 x 1.75 x 1.46; Ford Fiesta 4.04 x 1.73 x 1.48; VW Golf 4.28 x 1.79 x 1.46;
#:             Ford Focus 4.38 x 1.83 x 1.47
#:   sedan     Toyota Corolla 4.63 x 1.78 x 1.43; Toyota Camry 4.88 x 1.84 x 1.45;
#:             Mercedes E 4.95 x 1.85 x 1.47; Mercedes S 5.18 x 1.92 x 1.50
#:   sport     Audi TT 4.19 x 1.83 x 1.35; Porsche 911 4.52 x 1.85 x 1.30; Ford Mustang 4.79 x 1.92 x 1.38
#:   estate    Skoda Octavia Combi 4.69 x 1.83 x 1.47; VW Passat Variant 4.77 x 1.83 x 1.51;
#:             Volvo V90 4.94 x 1.88 x 1.48
#:   suv       Nissan Qashqai 4.43 x 1.84 x 1.63; Toyota RAV4 4.60 x 1.86 x 1.69;
#:             Ford Explorer 5.05 x 2.00 x 1.78; Chevrolet Tahoe 5.35 x 2.06 x 1.93
#:   pickup    Toyota Hilux double cab 5.33 x 1.86 x 1.82; Ford Ranger 5.37 x 1.92 x 1.88;
#:             Ford F-150 SuperCrew 5.89 x 2.03 x 1.96
#:   van       VW Caddy 4.50 x 1.86 x 1.80; Toyota Sienna 5.17 x 1.99 x 1.78; VW Transporter 4.90 x
#:             1.90 x 1.99; Ford Transit Custom 4.97 x 1.99 x 1.98; Mercedes Sprinter high roof
#:             5.93 x 2.02 x 2.70
#:   minibus   VW Caravelle LWB 5.30 x 1.90 x 1.97; Mercedes Vito Tourer 5.14 x 1.93 x 1.91;
#:             Ford Transit minibus L3H2 5.98 x 2.06 x 2.53
SEGMENT_SIZES_M: dict[str, tuple[tuple[float, float], ...]] = {
    "compact": ((3.3, 3.8), (1.55, 1.72), (1.40, 1.60)),
    "hatchback": ((3.9, 4.45), (1.70, 1.85), (1.40, 1.55)),
    "sedan": ((4.5, 5.3), (1.75, 1.95), (1.38, 1.55)),
    "sport": ((4.1, 4.9), (1.80, 1.95), (1.20, 1.40)),
    "estate": ((4.5, 5.0), (1.78, 1.90), (1.42, 1.55)),
    "suv": ((4.3, 5.4), (1.80, 2.10), (1.55, 1.95)),
    "pickup": ((5.2, 6.0), (1.80, 2.10), (1.75, 2.00)),
    "van": ((4.3, 6.0), (1.80, 2.10), (1.70, 2.75)),
    "minibus": ((5.0, 6.1), (1.85, 2.10), (1.85, 2.60)),
}


def car_kwargs(p: CarProfile, L: float, H: float) -> dict:
    """The keyword arguments of the car builder (``meshes._car``) for a model L x H."""
    return dict(bonnet=p.bonnet * L, ws_run=p.ws_run, rw_top_from_rear=p.rw_top * L,
                rw_base_from_rear=p.rw_base * L, belt=p.belt * H, nose_top=p.nose_top * H,
                tail_top=p.tail_top * H, wheel_r=p.wheel_r, tumble=p.tumble, clear=p.clear,
                rails=p.rails)

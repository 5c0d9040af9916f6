"""OpenStreetMap tag rules: which features become what, widths, heights, directions.

Every default here is documented in docs/osm.md; change them there too.
"""

from __future__ import annotations

import math
import re

__all__ = [
    "DRIVABLE",
    "SIDEWALK",
    "ROAD_CLASS",
    "SIDEWALK_WIDTH_M",
    "road_class",
    "road_params",
    "parse_metres",
    "parse_int",
    "building_height_m",
    "area_kind",
    "waterway_width_m",
    "kerb_parking",
    "RoadParams",
    "is_driveway",
    "RESIDENTIAL_BUILDINGS",
]

#: building=* values counted as residential (houses, garages) and as hard negatives (sheds)
#: in the metadata of an OSM scene (docs/osm.md).
RESIDENTIAL_BUILDINGS: dict[str, str] = {"house": "houses", "detached": "houses",
                                         "garage": "garages", "shed": "sheds"}


def is_driveway(tags) -> bool:
    """``highway=service`` + ``service=driveway``: a drivable way (road surface) whose
    stretch off the street becomes a driveway parking site (scene hint ``driveways``)."""
    return tags.get("highway") == "service" and tags.get("service") == "driveway"

#: highway=* classes that become drivable road: (lane width m, default width m two-way,
#: default width m one-way).
ROAD_CLASS: dict[str, tuple[float, float, float]] = {
    "motorway": (3.75, 11.0, 11.0),
    "trunk": (3.5, 14.0, 8.0),
    "primary": (3.5, 10.0, 7.0),
    "secondary": (3.25, 9.0, 6.5),
    "tertiary": (3.0, 7.5, 5.5),
    "motorway_link": (3.75, 6.0, 5.0),
    "trunk_link": (3.5, 6.0, 5.0),
    "primary_link": (3.5, 6.0, 5.0),
    "secondary_link": (3.25, 6.0, 5.0),
    "tertiary_link": (3.0, 6.0, 5.0),
    "unclassified": (3.0, 6.0, 4.5),
    "residential": (3.0, 6.5, 4.5),
    "living_street": (3.0, 5.0, 4.0),
    "service": (3.0, 5.0, 4.0),
    "road": (3.0, 6.0, 4.5),
}
DRIVABLE = frozenset(ROAD_CLASS)
#: classes with edge lines (solid, 0.3 m inside each edge)
EDGE_LINE_CLASSES = frozenset({"motorway", "trunk", "motorway_link", "trunk_link"})
#: classes that never get lane markings
UNMARKED_CLASSES = frozenset({"living_street", "service"})

#: highway=* classes that become sidewalk (not drivable) and their default width, metres.
SIDEWALK_WIDTH_M: dict[str, float] = {
    "footway": 2.0,
    "cycleway": 1.8,
    "path": 1.5,
    "pedestrian": 4.0,
}
SIDEWALK = frozenset(SIDEWALK_WIDTH_M)

#: building=* default heights (metres) when neither height nor building:levels is given.
BUILDING_HEIGHT_M: dict[str, float] = {
    "house": 7.0, "detached": 7.0, "semidetached_house": 7.0, "terrace": 9.0,
    "bungalow": 4.0, "residential": 12.0, "apartments": 15.0, "dormitory": 15.0,
    "commercial": 12.0, "retail": 8.0, "office": 18.0, "industrial": 9.0, "warehouse": 9.0,
    "garage": 3.0, "garages": 3.0, "carport": 2.5, "shed": 2.5, "hut": 3.0, "roof": 5.0,
    "church": 18.0, "cathedral": 30.0, "school": 12.0, "hospital": 20.0, "train_station": 12.0,
}
BUILDING_DEFAULT_HEIGHT_M = 10.0
LEVEL_HEIGHT_M = 3.0

#: waterway=* lines that become water surfaces, default width in metres.
WATERWAY_WIDTH_M: dict[str, float] = {"river": 12.0, "canal": 10.0, "stream": 2.0,
                                      "ditch": 1.0, "drain": 1.0}

_GRASS = {
    "landuse": {"grass", "meadow", "recreation_ground", "village_green", "cemetery",
                "allotments", "orchard", "vineyard", "forest", "flowerbed", "plant_nursery"},
    "leisure": {"park", "garden", "pitch", "playground", "golf_course", "common",
                "recreation_ground", "dog_park", "nature_reserve"},
    "natural": {"grassland", "scrub", "heath", "wood", "wetland", "fell"},
}
_SOIL = {"landuse": {"farmland", "construction", "brownfield", "greenfield", "quarry",
                     "landfill"}, "natural": {"sand", "bare_rock", "scree", "beach"}}
_WATER = {"natural": {"water", "bay"}, "waterway": {"riverbank", "dock", "boatyard"},
          "landuse": {"reservoir", "basin", "salt_pond"}, "leisure": {"swimming_pool"}}
_FOREST = {"landuse": {"forest"}, "natural": {"wood"}}

_NUM = re.compile(r"^\s*([0-9]+(?:[.,][0-9]+)?)\s*(m|meter|meters|metre|metres)?\s*$", re.I)
_INT = re.compile(r"^\s*([0-9]+)\s*$")


def parse_metres(value, lo: float = 0.1, hi: float = 500.0) -> float | None:
    """A length tag ("7", "7.5 m", "7,5") in metres, or None (feet, ranges, nonsense)."""
    if value is None:
        return None
    m = _NUM.match(str(value))
    if not m:
        return None
    v = float(m.group(1).replace(",", "."))
    return v if lo <= v <= hi else None


def parse_int(value, lo: int = 1, hi: int = 16) -> int | None:
    """An integer tag ("3"), or None (lists like "2;3", ranges, nonsense)."""
    if value is None:
        return None
    m = _INT.match(str(value))
    if not m:
        return None
    v = int(m.group(1))
    return v if lo <= v <= hi else None


def road_class(tags) -> str | None:
    """"road" for a drivable highway, "sidewalk" for foot/cycle ways, else None."""
    hw = tags.get("highway")
    if hw in DRIVABLE:
        if tags.get("area") == "yes" or tags.get("tunnel") in ("yes", "building_passage"):
            return None
        return "road"
    if hw in SIDEWALK:
        if tags.get("tunnel") == "yes":
            return None
        return "sidewalk"
    return None


class RoadParams:
    """Width, direction and lanes of one drivable way (see docs/osm.md).

    width_m        : ``width`` tag; else all lanes x the class's lane width; else the class
                     default (one-way or two-way)
    oneway         : ``oneway=yes|1|true|-1``; implied by ``junction=roundabout|circular`` and
                     ``highway=motorway`` unless ``oneway=no``
    reverse        : ``oneway=-1`` (traffic against the way's node order)
    lanes_forward / lanes_backward : from ``lanes``, ``lanes:forward``, ``lanes:backward``
                     (-1 = not tagged); forward is along the way (after ``reverse``)
    marking_lanes  : lanes used to draw dividers (tagged, else width / lane width)
    """

    __slots__ = ("cls", "width_m", "lane_width_m", "oneway", "reverse", "lanes_forward",
                 "lanes_backward", "marking_lanes", "width_source")

    def __init__(self, cls, width_m, lane_width_m, oneway, reverse, lanes_forward,
                 lanes_backward, marking_lanes, width_source):
        self.cls = cls
        self.width_m = width_m
        self.lane_width_m = lane_width_m
        self.oneway = oneway
        self.reverse = reverse
        self.lanes_forward = lanes_forward
        self.lanes_backward = lanes_backward
        self.marking_lanes = marking_lanes
        self.width_source = width_source


def road_params(tags) -> RoadParams:
    """Parameters of a drivable way from its tags."""
    cls = tags.get("highway")
    lane_w, w_two, w_one = ROAD_CLASS[cls]
    ow = str(tags.get("oneway", "")).strip().lower()
    if ow in ("yes", "1", "true"):
        oneway, reverse = True, False
    elif ow == "-1":
        oneway, reverse = True, True
    elif ow in ("no", "false", "0", "reversible", "alternating"):
        oneway, reverse = False, False
    else:
        oneway = tags.get("junction") in ("roundabout", "circular") or cls == "motorway"
        reverse = False
    lanes = parse_int(tags.get("lanes"))
    lf = parse_int(tags.get("lanes:forward"))
    lb = parse_int(tags.get("lanes:backward"), lo=0)
    if oneway:
        fw = lanes if lanes is not None else (lf if lf is not None else -1)
        bw = 0
    else:
        if lf is not None and lb is not None:
            fw, bw = lf, lb
        elif lanes is not None:
            if lf is not None:
                fw, bw = lf, max(lanes - lf, 0)
            elif lb is not None:
                fw, bw = max(lanes - lb, 0), lb
            else:
                fw, bw = (lanes + 1) // 2, lanes // 2
        else:
            fw = bw = -1
    total = (fw + bw) if fw >= 0 and bw >= 0 else None
    width = parse_metres(tags.get("width"), lo=1.0, hi=100.0)
    if width is not None:
        source = "width"
    elif total:
        width, source = total * lane_w, "lanes"
    else:
        width, source = (w_one if oneway else w_two), "default"
    if total:
        marking = total
    else:
        marking = max(1 if oneway else 2, int(math.floor(width / lane_w + 0.25)))
        if not oneway and marking % 2:
            marking -= 1
    return RoadParams(cls, float(width), lane_w, oneway, reverse, fw, bw, int(marking), source)


def building_height_m(tags) -> float:
    """``height``; else ``building:levels`` (+ ``roof:levels``) x 3 m; else the type default."""
    h = parse_metres(tags.get("height"), lo=1.0, hi=600.0)
    if h is not None:
        return h
    lv = parse_int(tags.get("building:levels"), lo=1, hi=200)
    if lv is not None:
        roof = parse_int(tags.get("roof:levels"), lo=0, hi=20) or 0
        return (lv + roof) * LEVEL_HEIGHT_M
    return BUILDING_HEIGHT_M.get(str(tags.get("building")), BUILDING_DEFAULT_HEIGHT_M)


def _match(tags, table) -> bool:
    return any(tags.get(k) in vals for k, vals in table.items())


def area_kind(tags) -> str | None:
    """What an area becomes: building, parking, parking_space (one bay, amenity=parking_space),
    water, forest, grass, soil, sidewalk or None."""
    b = tags.get("building")
    if b is not None and b != "no":
        return "building"
    hw = tags.get("highway")
    if hw is not None:
        return "sidewalk" if (hw in SIDEWALK and tags.get("area") == "yes") else None
    if tags.get("amenity") == "parking_space":
        return "parking_space"
    if tags.get("amenity") == "parking":
        if tags.get("parking") in ("underground", "multi-storey", "rooftop"):
            return None
        return "parking"
    if _match(tags, _WATER) or (tags.get("natural") == "water"):
        return "water"
    if _match(tags, _FOREST):
        return "forest"
    if _match(tags, _GRASS):
        return "grass"
    if _match(tags, _SOIL):
        return "soil"
    return None


def waterway_width_m(tags) -> float | None:
    """Width of a waterway line that becomes water (None: not such a line)."""
    ww = tags.get("waterway")
    if ww not in WATERWAY_WIDTH_M or tags.get("tunnel") in ("yes", "culvert"):
        return None
    return parse_metres(tags.get("width"), lo=0.3, hi=2000.0) or WATERWAY_WIDTH_M[ww]


_PARK_YES = {"lane", "street_side", "on_kerb", "half_on_kerb", "shoulder", "parallel", "diagonal",
             "perpendicular", "marked", "yes", "painted_area_only"}
_PARK_NO = {"no", "no_parking", "no_stopping", "fire_lane", "no_standing", "separate"}


def kerb_parking(tags) -> tuple[bool | None, bool | None]:
    """Whether cars may park along the (left, right) kerb of a way, relative to the way's
    node order, from ``parking:left|right|both`` (current scheme) or
    ``parking:lane:left|right|both`` (old scheme); None where the way says nothing."""

    def side(name):
        for key in (f"parking:{name}", f"parking:lane:{name}", "parking:both", "parking:lane:both"):
            v = str(tags.get(key, "")).strip().lower()
            if v in _PARK_YES:
                return True
            if v in _PARK_NO:
                return False
        return None

    return side("left"), side("right")

"""Names for what the map sees: the operator's names (and, in simulation, scene box ids) bound to the map's
objects, handed to tasks/ as `tasks.anchors.MapObjects` every control period.

The map keeps an object's id through re-association and relocation (a box pushed 20–50 cm is registered at
its new pose), so a bound name simply follows its id. When POCD removes the object (moved farther, or gone),
the name is lost and re-binds only to a *unique* candidate: a live, unnamed object of the box's known size
(within the map's association gate, x and y either way round) first mapped no earlier than `anchor_candidate_margin_s`
before the lost object was last observed, or standing where the lost object stood (the same box moved out of
view: two boxes cannot overlap), and never one that may be another named box: standing where that one stands
or stood, or nearer to it than to where the lost object stood (`_rebind`); with several, the name waits
("box_3: 2 candidates"), with none "box_3 not in the map". "Where a box stood" is its footprint at its known size
(declared, else measured from both sides, else as mapped): a box is often mapped smaller than it is (0.5 m for a
0.6 m box seen from one side), and a new object is often a partial view. A name never bound binds to the object
nearest to where it was given (the sequence's `objects`), or in simulation to where its scene box is, within
`anchor_bind_radius_m`.

The yaw a name sees is continuous from its binding: the box fit keeps yaw within ±45°, so the raw yaw jumps
by 90° as a box turns; it is unwrapped by quarter turns toward the previous one (x and y extents swapped on
odd turns, the seen sides turned with them), which keeps each face's label on the same physical face.

With each named object go which of its side faces the map saw (`MappedObject.sides_seen`)
and its size if known: declared with the name (`objects: {box_3: {size: [...]}}`, x and y matched to the
mapped extent either way round), else measured along an axis while both its side faces were seen. Anchors
are placed from those (`tasks.anchors.anchor_box`).
"""

from __future__ import annotations

import copy
import logging
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from app.footprint_overlap import overlap_depth
from app.object_label import object_id_of, shown_id
from app.runtime.ground_truth_map import GroundTruthMap
from core.errors import StudioError
from core.mapping.world_map import WorldMap
from core.params import MappingParams, SequencerParams
from core.sim.world import SimWorld
from core.types import MappedObject, ObjectMapSnapshot, ObjectStatus
from tasks.anchors import MapObjects, ObjectView
from tasks.schema import NamedObject, TaskSequence

log = logging.getLogger(__name__)


class UnknownObjectError(StudioError, LookupError):
    """No object of that id in the map (or no object of that name)."""


class NameTakenError(StudioError, ValueError):
    """The name is bound to another object, or the object has another name."""


class NameInUseError(StudioError, ValueError):
    """A name that anchored subtasks use cannot be taken away."""


@dataclass(frozen=True)
class SeenObject:
    """A mapped object (or, with the ground-truth map, a true box) as the naming sees it."""

    id: str
    position: np.ndarray
    yaw: float
    extent: np.ndarray
    consistency: float = 1.0
    observations: int = -1
    """How often the map has matched it (−1: the true box of the ground-truth map, always observed)."""
    sides_seen: np.ndarray | None = None
    """Side faces its points show (2×2 bool: axis x, y; −, + side); None: all (the true box)."""

    @staticmethod
    def of(obj: MappedObject) -> SeenObject:
        R = obj.pose[:3, :3]
        sides = None if obj.sides_seen is None else np.asarray(obj.sides_seen, bool).copy()
        return SeenObject(object_id_of(obj.id), obj.pose[:3, 3].copy(), float(math.atan2(R[1, 0], R[0, 0])),
                          np.asarray(obj.extent, float).copy(), obj.consistency, obj.observations, sides)


def seen_objects(snapshot: ObjectMapSnapshot) -> list[SeenObject]:
    return [SeenObject.of(o) for o in snapshot.objects if o.status == ObjectStatus.ACTIVE]


@dataclass
class _Binding:
    object_id: str | None = None
    yaw: float = 0.0
    extent: np.ndarray | None = None
    observations: int = -1
    last_seen_t: float = -math.inf
    lost: bool = False
    sides_seen: np.ndarray | None = None
    """The object's seen side faces along the binding's (continuous) axes."""
    measured: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    """Its extent along each axis the last time both side faces of that axis were seen (NaN: never)."""
    position: np.ndarray | None = None
    """Where its object was last (world, m)."""
    size: tuple[float, float, float] | None = None
    """The full size the operator declared when naming it (m; None: as the sequence declares, if it does)."""


def quarter_turns(raw: float, previous: float) -> int:
    """How many quarter turns bring `raw` within 45° of `previous`."""
    return round((previous - raw) / (math.pi / 2))


def continuous_yaw(raw: float, previous: float, extent: np.ndarray) -> tuple[float, np.ndarray]:
    """`raw` shifted by quarter turns to lie within 45° of `previous`, and the extent along the new axes."""
    k = quarter_turns(raw, previous)
    ext = np.asarray(extent, float).copy()
    if k % 2:
        ext[[0, 1]] = ext[[1, 0]]
    return raw + k * math.pi / 2, ext


def turn_sides(sides: np.ndarray | None, k: int) -> np.ndarray | None:
    """Seen sides (2×2: axis x, y; −, +) along axes turned by `k` quarter turns: after one, the new x axis is the
    old y and the new y the old −x."""
    if sides is None:
        return None
    out = np.asarray(sides, bool).copy()
    for _ in range(k % 4):
        out = np.array([out[1], out[0][::-1]])
    return out


def matched_size(size: tuple[float, float, float], extent: np.ndarray) -> np.ndarray:
    """A declared size along the mapped box's axes: x and y in the order nearer its extent."""
    s = np.asarray(size, float)
    swapped = s[[1, 0, 2]]
    e = np.asarray(extent, float)
    return s if np.sum(np.abs(s[:2] - e[:2])) <= np.sum(np.abs(swapped[:2] - e[:2])) else swapped


def same_extent(a: np.ndarray, b: np.ndarray, gate_m: float) -> bool:
    """Whether two extents match within the gate, x and y either way round."""
    xy = np.abs(np.sort(a[:2]) - np.sort(b[:2]))
    return bool(np.all(xy <= gate_m) and abs(float(a[2] - b[2])) <= gate_m)


class ObjectNames:
    """Owns name → object bindings of one run; `view` updates them from a map snapshot (call every period)."""

    def __init__(self, params: SequencerParams | None = None, mapping: MappingParams | None = None) -> None:
        self.params = params or SequencerParams()
        self.gate_m = (mapping or MappingParams()).association_gate_m
        self._bindings: dict[str, _Binding] = {}
        self._first_seen: dict[str, float] = {}
        self._declared: Mapping[str, NamedObject] = {}

    def name(self, name: str, obj: SeenObject, t: float,
             size: tuple[float, float, float] | None = None) -> Callable[[], None]:
        """The operator names `obj`, with its full `size` (m) if known: it holds at once, also while a run keeps
        its own copy of the sequence (any earlier name of it is dropped). Returns what puts the bindings back as
        they were (for a naming whose sequence is then refused)."""
        before = copy.deepcopy(self._bindings)
        for other, b in self._bindings.items():
            if b.object_id == obj.id and other != name:
                b.object_id, b.lost = None, True
        self._bindings[name] = _Binding(obj.id, obj.yaw, obj.extent.copy(), obj.observations, t,
                                        sides_seen=obj.sides_seen, position=obj.position.copy(), size=size)

        def undo() -> None:
            self._bindings.clear()
            self._bindings.update(before)
        return undo

    def check_free(self, name: str, object_id: str) -> None:
        """Raise `NameTakenError` unless `name` may name `object_id`: the name is not bound to another object now
        (a lost name may be given again) and the object has no other name."""
        bound = self.bound()
        holder = bound.get(name)
        if holder is not None and holder != object_id:
            raise NameTakenError(f"{name} names {shown_id(holder)}: unname it first")
        other = next((n for n, oid in bound.items() if oid == object_id and n != name), None)
        if other is not None:
            raise NameTakenError(f"{shown_id(object_id)} is named {other}: unname it first")

    def forget(self, name: str) -> None:
        """Drop `name` and its binding."""
        self._bindings.pop(name, None)

    def bound(self) -> dict[str, str]:
        """Name → object id of the names bound now."""
        return {n: b.object_id for n, b in self._bindings.items() if b.object_id is not None}

    def view(self, t: float, objects: Iterable[SeenObject], names: Mapping[str, NamedObject],
             truth: Mapping[str, np.ndarray] | None = None, merged: Mapping[str, str] | None = None) -> MapObjects:
        """Bind, follow and re-bind every name in `names` (`truth`: scene box id → true centre, simulation
        only, for names never bound; `merged`: object id → the live object the map merged it into) and return the
        objects as tasks/ sees them."""
        live = {o.id: o for o in objects}
        self._declared = names
        for oid in live:
            self._first_seen.setdefault(oid, t)
        unresolved: dict[str, str] = {}
        for name, declared in names.items():
            why = self._update(name, declared, live, t, truth or {}, merged or {})
            if why:
                unresolved[name] = why
        by_object = {b.object_id: (n, b) for n, b in self._bindings.items() if b.object_id in live}
        views = []
        for oid, o in live.items():
            name, b = by_object.get(oid, (None, None))
            if b is None or name is None:
                views.append(ObjectView(oid, name, o.position.copy(), o.yaw, o.extent.copy(), o.consistency,
                                        sides_seen=o.sides_seen))
                continue
            extent = np.asarray(b.extent, float)
            declared = self._declared_size(name, b)
            size = matched_size(declared, extent) if declared is not None else b.measured
            views.append(ObjectView(oid, name, o.position.copy(), b.yaw, extent, o.consistency,
                                    sides_seen=b.sides_seen, size=None if np.isnan(size[:2]).all() else size))
        return MapObjects(t, tuple(views), unresolved, self._last_known(unresolved, names))

    def _last_known(self, unresolved: Iterable[str], names: Mapping[str, NamedObject]) -> dict[str, np.ndarray]:
        """Where each unresolved name's object was last mapped, else where the sequence declared it (none for a
        name known only from the simulated scene: the robot is not told where a box it has not seen is)."""
        out = {}
        for name in unresolved:
            b = self._bindings.get(name)
            declared = names[name].position
            if b is not None and b.position is not None:
                out[name] = np.asarray(b.position, float).copy()
            elif declared is not None:
                out[name] = np.asarray(declared, float).copy()
        return out

    def _update(self, name: str, declared: NamedObject, live: dict[str, SeenObject], t: float,
                truth: Mapping[str, np.ndarray], merged: Mapping[str, str]) -> str:
        b = self._bindings.setdefault(name, _Binding())
        if b.object_id is not None and b.object_id not in live:
            self._follow_merge(name, b, live, merged)
        if b.object_id is not None and b.object_id in live:
            self._follow(b, live[b.object_id], t)
            return ""
        if b.object_id is not None:  # removed from the map (POCD) or merged into another object
            log.info("%s lost: %s is no longer in the map (last at %s)", name, b.object_id,
                     None if b.position is None else np.round(b.position[:2], 2).tolist())
            b.object_id, b.lost = None, True
        taken = {x.object_id for x in self._bindings.values() if x.object_id is not None}
        free = [o for o in live.values() if o.id not in taken]
        if b.lost:
            return self._rebind(name, b, free, t)
        hint = truth.get(name) if declared.position is None else np.asarray(declared.position, float)
        if hint is None:
            return f"{name} not yet seen"
        near = [o for o in free if float(np.linalg.norm(o.position[:2] - hint[:2])) <= self.params.anchor_bind_radius_m]
        if not near:
            return f"{name} not yet seen"
        best = min(near, key=lambda o: float(np.linalg.norm(o.position[:2] - hint[:2])))
        self._bindings[name] = _Binding(best.id, best.yaw, best.extent.copy(), best.observations, t,
                                        sides_seen=best.sides_seen, position=best.position.copy())
        return ""

    def _follow_merge(self, name: str, b: _Binding, live: dict[str, SeenObject], merged: Mapping[str, str]) -> None:
        """The map merged the named object into another (the association found them one surface): the name goes
        with it, unless another name holds that object."""
        into = merged.get(b.object_id or "")
        if into is None or into not in live or any(x.object_id == into for x in self._bindings.values()):
            return
        log.info("%s: %s merged into %s, the name goes with it", name, b.object_id, into)
        b.object_id = into

    def _follow(self, b: _Binding, o: SeenObject, t: float) -> None:
        b.position = o.position.copy()
        k = quarter_turns(o.yaw, b.yaw)
        b.yaw, b.extent = continuous_yaw(o.yaw, b.yaw, o.extent)
        b.sides_seen = turn_sides(o.sides_seen, k)
        if b.sides_seen is not None:
            both = b.sides_seen.all(axis=1)
            b.measured[:2] = np.where(both, b.extent[:2], b.measured[:2])
        if o.observations != b.observations or o.observations < 0:
            b.observations, b.last_seen_t = o.observations, t

    def _rebind(self, name: str, b: _Binding, free: list[SeenObject], t: float) -> str:
        since = b.last_seen_t - self.params.anchor_candidate_margin_s
        extent = self.known_size(name, b)  # not as last mapped: a fused box was mapped 1.19 m long before removal
        others = {n: x for n, x in self._bindings.items() if n != name and x.position is not None}
        candidates = []
        for o in free:
            if not same_extent(o.extent, extent, self.gate_m):
                continue
            new, here = self._first_seen.get(o.id, t) >= since, self._overlaps(name, b, o)
            theirs = self._claimed_by(name, b, o, others)
            log.debug("%s: %s at %s: new %s, where it stood %s, another's %s", name, o.id,
                      np.round(o.position[:2], 2).tolist(), new, here, theirs or "-")
            if (new or here) and not theirs:
                candidates.append(o)
        if not candidates:
            return f"{name} not in the map"
        if len(candidates) > 1:
            return f"{name}: {len(candidates)} candidates"
        o = candidates[0]
        yaw, ext = continuous_yaw(o.yaw, b.yaw, o.extent)
        moved = math.nan if b.position is None else float(np.linalg.norm(o.position[:2] - b.position[:2]))
        log.info("%s re-bound to %s at %s, %.2f m from where it stood", name, o.id,
                 np.round(o.position[:2], 2).tolist(), moved)
        self._bindings[name] = _Binding(o.id, yaw, ext, o.observations, t, sides_seen=turn_sides(
            o.sides_seen, quarter_turns(o.yaw, b.yaw)), measured=b.measured,  # the same box: its size stays
            position=o.position.copy(), size=b.size)
        return ""

    def _claimed_by(self, name: str, b: _Binding, o: SeenObject, others: Mapping[str, _Binding]) -> str:
        """The other named box `o` may be ('' if none): it stands where that one stands (or stood, if lost), or
        nearer to it than to where `name`'s object stood. Boxes here are identical, and a box moved while unseen
        is found near where it was: on the bench's lap 3 (seed 1, localization on) box_a's object was removed as
        box_c's new place was first mapped, 2.7 m from box_a and 0.36 m from box_c, which was mapped 0.5 m wide
        (seen from one side) and its old object not yet removed; box_a took it and its pick completed 2.8 m off."""
        if b.position is None:
            return ""
        own = float(np.linalg.norm(o.position[:2] - b.position[:2]))
        for other, x in others.items():
            assert x.position is not None
            if self._overlaps(other, x, o) or float(np.linalg.norm(o.position[:2] - x.position[:2])) < own:
                return other
        return ""

    def _declared_size(self, name: str, b: _Binding) -> tuple[float, float, float] | None:
        """The size declared for `name`: given with the name, else in the sequence's `objects`."""
        if b.size is not None:
            return b.size
        named = self._declared.get(name)
        return named.size if named is not None else None

    def known_size(self, name: str, b: _Binding) -> np.ndarray:
        """The full size of `name`'s box along its binding's axes: declared, else measured where both faces of an
        axis were seen, else as mapped. Re-binding compares candidates with it: the bench's lap 2 (seed 4,
        localization on) mapped box_a 1.19 m long (its old and new places fused) just before POCD removed it, and
        its new object (0.37 x 0.58 m seen, 8 cm from where it stood) failed the extent gate against that, so the
        name waited 'box_a not in the map' until its approach timed out."""
        mapped = np.asarray(b.extent if b.extent is not None else np.zeros(3), float)
        declared = self._declared_size(name, b)
        if declared is not None:
            return matched_size(declared, mapped)
        return np.where(np.isfinite(b.measured), b.measured, mapped)

    def _overlaps(self, name: str, b: _Binding, o: SeenObject) -> bool:
        """Does `o` stand where `name`'s box stands or stood: the two footprints, both at that box's known size
        (`o` may be a partial view of it), overlap by more than `anchor_overlap_margin_m`? Two boxes cannot stand in
        one place: it is the same box, moved while out of view. Such a box is mapped as a new object while the old
        one is still matched (the two overlap) until POCD removes it, so it is older than the
        `anchor_candidate_margin_s` window allows (the bench's lap 2, seed 3: box_c moved 0.42 m while unseen, its
        new place first mapped at 24.4 s, the old object matched at E[v] 1.0 until 27.7 s and removed at 29.4 s; the
        centres 0.48 m apart, 0.24 and 0.41 m along the box's axes: a circle test at the smaller side less the
        margin, 0.44 m, missed it and the name waited 'box_c not in the map' until its approach timed out)."""
        if b.position is None or b.extent is None:
            return False
        size = self.known_size(name, b)
        depth = overlap_depth(b.position, b.yaw, size, o.position, o.yaw, size)
        return depth > self.params.anchor_overlap_margin_m


def map_objects(names: ObjectNames, world_map: WorldMap, sequence: TaskSequence, world: SimWorld | None,
                t: float) -> MapObjects | None:
    """What the sequencer sees of the map for `sequence`'s named objects and the names the operator gave since
    (None when there are none): the object map's live objects, or with the ground-truth map the simulated boxes
    themselves."""
    if not sequence.objects and not names.bound():
        return None
    truth = None if world is None else {b.id: np.asarray(b.position, float) for b in world.boxes()}
    seen, merged = _seen_and_merged(world_map, world)
    return names.view(t, seen, sequence.objects, truth, merged)


def find_object(world_map: WorldMap, world: SimWorld | None, object_id: str) -> SeenObject | None:
    """The live object `object_id` of the map (with the ground-truth map, the scene box of that id)."""
    return next((o for o in _seen(world_map, world) if o.id == object_id), None)


def _seen(world_map: WorldMap, world: SimWorld | None) -> list[SeenObject]:
    """The map's live objects; with the ground-truth map, the simulated boxes themselves (ids = box ids)."""
    return _seen_and_merged(world_map, world)[0]


def _seen_and_merged(world_map: WorldMap, world: SimWorld | None) -> tuple[list[SeenObject], dict[str, str]]:
    """`_seen`, and from the same snapshot each merged object's id → the live object it went into (none with the
    ground-truth map)."""
    if isinstance(world_map, GroundTruthMap) and world is not None:
        return [SeenObject(b.id, np.asarray(b.position, float), float(b.yaw), np.asarray(b.size, float))
                for b in world.boxes()], {}
    snapshot = world_map.snapshot()
    merged = {object_id_of(gone): object_id_of(keep) for gone, keep in snapshot.merged_into.items()}
    return seen_objects(snapshot), merged

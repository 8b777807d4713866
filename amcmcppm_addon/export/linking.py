"""Light and shadow linking (Object > Shading > Light Linking) -> the core's receiver and
blocker sets.

Blender's rules (its depsgraph light-linking cache, which Cycles reads): an emitter, a light or
an emissive mesh object, with a receiver collection lights an object unless the collection
excludes it, and, when the collection includes any object, only the objects it includes.  An
object's state in a collection is that of the collection's own entry for it, or else of the
child collection (first level) that holds it, however deep; the collection's own entries win,
and among children the last.  An emitter without a receiver collection lights everything.  The
blocker collection says in the same way which objects shadow the emitter.

Objects lit (or shadowing) alike for every emitter share a receiver (blocker) set
(``Scene.receiver_sets``, ``Scene.blocker_sets``); an emitter's links (``Lights.links``,
``Scene.emitter_links``; ``Lights.shadow_links``, ``Scene.emitter_shadow_links``) have bit s set
when it lights (is shadowed by) set s.  Set 0 holds the objects no collection names.  Cycles
allows 64 sets of each kind; so does the core.
"""
from __future__ import annotations

import numpy as np

from ...core.scene import ALL_LINKS, MAX_RECEIVER_SETS

INCLUDE, EXCLUDE = 1, 2


def _original(data):
    """The original datablock of an evaluated one (identity for the objects' light linking)."""
    return getattr(data, "original", None) or data


def _key(ob):
    return _original(ob).as_pointer()


def _state(link):
    return EXCLUDE if link.light_linking.link_state == "EXCLUDE" else INCLUDE


def collection_states(collection) -> dict:
    """{object key: INCLUDE or EXCLUDE} of a receiver collection (Blender's precedence)."""
    states = {}
    # collection_children and collection_objects hold the link states, in the order of children
    # and objects.
    for child, link in zip(collection.children, collection.collection_children):
        state = _state(link)
        for ob in child.all_objects:
            states[_key(ob)] = state
    for ob, link in zip(collection.objects, collection.collection_objects):
        states[_key(ob)] = _state(link)
    return states


class LightLinking:
    """The receiver (or blocker) collections of a depsgraph's emitters and the sets found so far."""

    def __init__(self, emitters, collections, log, kind="receiver"):
        """emitters : {object key: collection index}; collections : list of
        :func:`collection_states` dicts; kind : "receiver" or "blocker" (for messages)."""
        self.kind = kind
        self.emitters = emitters
        self.collections = collections
        self.has_include = [INCLUDE in states.values() for states in collections]
        self.log = log
        default = tuple(not inc for inc in self.has_include)      # objects no collection names
        self.sets = {default: 0}
        self._objects = {}

    @staticmethod
    def from_depsgraph(depsgraph, log, kind="receiver"):
        """The depsgraph's light linking (``kind`` "receiver") or shadow linking ("blocker"), or
        None when no emitter has such a collection."""
        emitters, index, collections = {}, {}, []
        for data in depsgraph.ids:
            links = getattr(data, "light_linking", None)
            coll = getattr(links, f"{kind}_collection", None)
            if coll is None:
                continue
            coll = _original(coll)
            c = index.get(coll.as_pointer())
            if c is None:
                c = index[coll.as_pointer()] = len(collections)
                collections.append(collection_states(coll))
            emitters[_key(data)] = c
        return LightLinking(emitters, collections, log, kind) if collections else None

    def object_set(self, ob) -> int:
        """The receiver (blocker) set of object ``ob``: its vector over the collections of
        being lit by (shadowing) their emitters."""
        k = _key(ob)
        s = self._objects.get(k)
        if s is None:
            lit = tuple(states.get(k) != EXCLUDE and (not inc or states.get(k) == INCLUDE)
                        for states, inc in zip(self.collections, self.has_include))
            s = self.sets.get(lit)
            if s is None:
                if len(self.sets) >= MAX_RECEIVER_SETS:
                    self.log.warning(f"{'light' if self.kind == 'receiver' else 'shadow'} linking: more "
                                     f"than {MAX_RECEIVER_SETS} different {self.kind} sets; '{ob.name}' "
                                     "and later ones are taken as objects no collection names")
                    s = 0
                else:
                    s = self.sets[lit] = len(self.sets)
            self._objects[k] = s
        return s

    def collection(self, ob) -> int:
        """The collection index of emitter ``ob``, or -1 (it lights everything, or everything
        shadows it)."""
        return self.emitters.get(_key(ob), -1)

    def masks(self) -> np.ndarray:
        """(C,) uint64 the links of each collection's emitters over the sets found."""
        out = np.zeros(len(self.collections), np.uint64)
        for lit, s in self.sets.items():
            for c, on in enumerate(lit):
                if on:
                    out[c] |= np.uint64(1) << np.uint64(s)
        return out

    def links(self, collections) -> np.ndarray:
        """(n,) uint64 links of emitters with collection indices ``collections`` (-1: all)."""
        c = np.asarray(collections, np.int64)
        masks = self.masks()
        return np.where(c >= 0, masks.take(np.maximum(c, 0)) if len(masks) else ALL_LINKS, ALL_LINKS)

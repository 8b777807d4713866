"""Light linking (Object > Shading > Light Linking > Receivers) -> the core's receiver sets.

Blender's rules (its depsgraph light-linking cache, which Cycles reads): an emitter, a light or
an emissive mesh object, with a receiver collection lights an object unless the collection
excludes it, and, when the collection includes any object, only the objects it includes.  An
object's state in a collection is that of the collection's own entry for it, or else of the
child collection (first level) that holds it, however deep; the collection's own entries win,
and among children the last.  An emitter without a receiver collection lights everything.

Objects lit alike by every emitter share a receiver set (``Scene.receiver_sets``); an emitter's
links (``Lights.links``, ``Scene.emitter_links``) have bit s set when it lights set s.  Set 0
holds the objects no collection names.  Cycles allows 64 sets; so does the core.
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
    """The receiver collections of a depsgraph's emitters and the receiver sets found so far."""

    def __init__(self, emitters, collections, log):
        """emitters : {object key: collection index}; collections : list of
        :func:`collection_states` dicts."""
        self.emitters = emitters
        self.collections = collections
        self.has_include = [INCLUDE in states.values() for states in collections]
        self.log = log
        default = tuple(not inc for inc in self.has_include)      # objects no collection names
        self.sets = {default: 0}
        self._objects = {}

    @staticmethod
    def from_depsgraph(depsgraph, log):
        """The depsgraph's light linking, or None when no emitter has a receiver collection."""
        emitters, index, collections = {}, {}, []
        for data in depsgraph.ids:
            links = getattr(data, "light_linking", None)
            coll = getattr(links, "receiver_collection", None)
            if coll is None:
                continue
            coll = _original(coll)
            c = index.get(coll.as_pointer())
            if c is None:
                c = index[coll.as_pointer()] = len(collections)
                collections.append(collection_states(coll))
            emitters[_key(data)] = c
        return LightLinking(emitters, collections, log) if collections else None

    def receiver_set(self, ob) -> int:
        """The receiver set of object ``ob`` (its lit-by vector over the collections)."""
        k = _key(ob)
        s = self._objects.get(k)
        if s is None:
            lit = tuple(states.get(k) != EXCLUDE and (not inc or states.get(k) == INCLUDE)
                        for states, inc in zip(self.collections, self.has_include))
            s = self.sets.get(lit)
            if s is None:
                if len(self.sets) >= MAX_RECEIVER_SETS:
                    self.log.warning(f"light linking: more than {MAX_RECEIVER_SETS} different receiver "
                                     f"sets; '{ob.name}' and later ones are lit as unnamed objects")
                    s = 0
                else:
                    s = self.sets[lit] = len(self.sets)
            self._objects[k] = s
        return s

    def collection(self, ob) -> int:
        """The receiver collection index of emitter ``ob``, or -1 (it lights everything)."""
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

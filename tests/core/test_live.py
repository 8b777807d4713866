"""The live render of the 3D viewport (``core/live.py``): a server process that renders the newest
job, publishes every pass and leaves a job when a newer one comes."""
import dataclasses
import os
import time

import numpy as np
import pytest

from core import RenderSettings, render
from core.accel import SPLIT_MIN_TRIANGLES, SplitScene
from core.camera import generate_camera_rays
from core.context import RenderContext
from core.live import LiveRender, preview_camera
from core.scene import Camera, Materials
from core.testing.scenes import BUILTIN, MeshBuilder, subdivide

FAST = dict(method="ppm", photons_per_pass=20_000, workers=1)


def wait(live, until, timeout=120.0):
    """Poll ``live.latest()`` until ``until(images)``; returns the (image, stats) seen."""
    seen, t0 = [], time.monotonic()
    while not until(seen):
        ended = not live.running        # (before the read: an image written just before the end counts)
        got = live.latest()
        if got is not None:
            seen.append(got)
        elif ended:
            break
        assert time.monotonic() - t0 < timeout, f"no end after {timeout} s: {[s for _, s in seen]}"
        time.sleep(0.02)
    return seen


@pytest.fixture
def live():
    live = LiveRender()
    yield live
    live.close()


def test_a_live_render_publishes_every_pass_of_the_image_a_render_makes(live):
    """One job: each pass's image in turn (none missed with a quick reader), the last one the
    very image ``core.render`` makes of the scene with the same settings, then nothing new."""
    scene = BUILTIN["cornell_box"](resolution=(24, 18))
    settings = RenderSettings(passes=3, **FAST)
    live.start(scene, settings)
    seen = wait(live, lambda s: bool(s) and s[-1][1]["pass"] == 3)
    assert [s["pass"] for _, s in seen][-1] == 3 and len(seen) >= 2
    final = seen[-1][0]
    assert final.shape == (18, 24, 4) and np.isfinite(final).all() and final[..., :3].mean() > 0.05
    assert np.array_equal(final, render(scene, settings).image)
    deadline = time.monotonic() + 30
    while live.running:
        assert time.monotonic() < deadline
        time.sleep(0.02)
    assert live.latest() is None                    # the last pass was returned already


def test_a_large_image_shows_a_coarse_preview_first(live):
    """A job whose image has over ``PREVIEW_PIXELS`` pixels publishes a preview first (pass 0): one
    pass of uniform photons with the image's sides halved until it is small enough (320 x 240:
    once), the very image of such a render; then its own passes, the last a render's bit for bit.
    A smaller image gets none."""
    scene = BUILTIN["cornell_box"](resolution=(320, 240))
    settings = RenderSettings(passes=2, **dict(FAST, method="amcmcppm", chains=256))
    small = preview_camera(scene.camera)
    assert small.resolution == (160, 120) and preview_camera(small) is None
    live.start(scene, settings)
    seen = wait(live, lambda s: bool(s) and s[-1][1]["pass"] == 2)
    previews = [(image, stats) for image, stats in seen if stats["preview"]]
    assert len(previews) == 1 and previews[0][1]["pass"] == 0 and seen[0][1]["preview"]
    reference = render(dataclasses.replace(scene, camera=small),
                       dataclasses.replace(settings, passes=1, method="ppm")).image
    assert previews[0][0].shape == (120, 160, 4) and np.array_equal(previews[0][0], reference)
    assert [stats["pass"] for _, stats in seen[1:]] == sorted({stats["pass"] for _, stats in seen[1:]})
    assert seen[-1][0].shape == (240, 320, 4)
    assert np.array_equal(seen[-1][0], render(scene, settings).image)


def test_a_new_job_supersedes_the_running_one(live):
    """A long job is left as soon as the next one starts: from then on only the new job's images
    come, of its own size, and the old one's stop file ends it between photon batches.  A job that
    changes only the camera sends no scene (the server renders the one it holds through the new
    camera: the image ``core.render`` makes of the moved scene, bit for bit); a changed scene is
    sent again, and the files of the jobs before go."""
    scene = BUILTIN["cornell_box"](resolution=(24, 18))
    live.start(scene, RenderSettings(passes=10_000, **FAST))
    wait(live, lambda s: len(s) >= 1)
    pose = scene.camera.world_from_camera.copy()
    pose[0, 3] += 0.2
    moved = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, resolution=(16, 12),
                                                                  world_from_camera=pose))
    settings = RenderSettings(passes=2, **FAST)
    live.start(moved, settings)
    seen = wait(live, lambda s: bool(s) and s[-1][1]["pass"] == 2)
    assert live.job == 2 and all(image.shape == (12, 16, 4) for image, _ in seen)
    assert np.array_equal(seen[-1][0], render(moved, settings).image)
    names = set(os.listdir(live.folder))
    assert "scene1.npz" in names and "scene2.npz" not in names
    changed = BUILTIN["cornell_box"](resolution=(16, 12))       # (the same, but new objects)
    live.start(changed, settings)
    seen = wait(live, lambda s: bool(s) and s[-1][1]["pass"] == 2)
    assert live.job == 3 and np.array_equal(seen[-1][0], render(changed, settings).image)
    names = set(os.listdir(live.folder))
    # (a job the next one stopped may still write its last image: gone at the start after)
    assert "scene3.npz" in names and not names & {"scene1.npz", "image1.npy", "image2.npy"}


def test_a_context_seen_through_another_camera_renders_as_a_new_one():
    """``RenderContext.with_camera``: rendering through it is rendering the moved scene from scratch,
    bit for bit, also when the camera leaves the glowing gas it was in (the eye's medium, cached by
    the first render, is found again); a context of another scene is refused."""
    scene = BUILTIN["glowing_glass_ball"](resolution=(16, 12))
    inside = Camera.look_at((0.0, 0.2, 0.351), (1.0, 0.2, 0.351), lens_mm=24.0, resolution=(16, 12))
    in_gas = dataclasses.replace(scene, camera=inside)
    settings = RenderSettings(passes=2, **FAST)
    ctx = RenderContext(in_gas)
    first = render(in_gas, settings, context=ctx).image
    assert ctx.camera_medium(np.zeros((1, 3)))[0] >= 0                      # (in the gas)
    assert np.array_equal(first, render(in_gas, settings).image)
    moved = ctx.with_camera(scene.camera)
    assert moved.accel is ctx.accel and moved.camera_medium(np.zeros((1, 3)))[0] < 0
    assert np.array_equal(render(moved.source, settings, context=moved).image, render(scene, settings).image)
    with pytest.raises(ValueError, match="another scene"):
        render(scene, settings, context=ctx)


def test_a_failed_job_raises_its_error_and_close_ends_the_server(live):
    """A scene the server cannot render: ``latest`` raises with the server's message (not a hang),
    and ``close`` ends the process and removes the files."""
    scene = BUILTIN["cornell_box"](resolution=(8, 6))
    clipped = dataclasses.replace(scene.camera, clip_start=5.0, clip_end=1.0)
    broken = dataclasses.replace(scene, camera=clipped)
    live.start(broken, RenderSettings(passes=2, **FAST))
    t0 = time.monotonic()
    with pytest.raises(RuntimeError, match="clip"):
        while time.monotonic() - t0 < 60:
            live.latest()
            time.sleep(0.02)
    assert not live.running
    proc, folder = live.proc, live.folder
    live.close()
    assert proc.poll() is not None and not os.path.exists(folder) and live.proc is None


def test_an_edit_that_keeps_the_triangles_keeps_the_bvh():
    """``RenderContext(reuse=...)``, the live server's edited scenes: an edited material or light
    keeps the earlier context's embree scenes (the whole scene's and the contact scene without the
    glass) and triangle data, and renders as a fresh context does, bit for bit; a moved vertex
    (of a scene too small for ``SplitScene``) and a scene moved far away keep nothing; a light that
    moves the scene's bounds by less than ``FRAME_SHIFT`` keeps embree's frame and so everything,
    and renders as a fresh context does but for paths its spawn offsets set apart; glass made
    diffuse keeps the whole scene's but has no contact scene."""
    scene = BUILTIN["glass_ceiling_room"](resolution=(16, 12))
    settings = RenderSettings(passes=2, **FAST)
    ctx = RenderContext(scene)
    assert ctx.accel._contact is not None
    colours = scene.materials.diffuse_color.copy()
    colours[0] *= 0.5
    recoloured = dataclasses.replace(scene, materials=dataclasses.replace(scene.materials,
                                                                          diffuse_color=colours))
    brighter = dataclasses.replace(scene, lights=dataclasses.replace(scene.lights,
                                                                     power=scene.lights.power * 2))
    for edited in (recoloured, brighter):
        kept = RenderContext(edited, reuse=ctx)
        assert kept.accel._embree is ctx.accel._embree and kept.accel._contact is ctx.accel._contact
        assert kept.accel.v0 is ctx.accel.v0
        assert np.array_equal(render(edited, settings, context=kept).image, render(edited, settings).image)
    vertices = scene.vertices.copy()
    vertices[0] += 1e-3
    position = scene.lights.position.copy()
    position[0, 2] += 5.0                                   # (above the room's top: new bounds)
    glassless = scene.materials.dielectric_weight.copy()
    glassless[:] = 0.0
    moved_light = dataclasses.replace(scene, lights=dataclasses.replace(scene.lights, position=position))
    far = scene.vertices + np.float32(20.0)                 # (everything moved 3 extents away)
    moved_all = dataclasses.replace(scene, vertices=far, lights=dataclasses.replace(
        scene.lights, position=scene.lights.position + 20.0))
    for edited in (dataclasses.replace(scene, vertices=vertices), moved_all):
        fresh = RenderContext(edited.validate(), reuse=ctx)
        assert fresh.accel._embree is not ctx.accel._embree and fresh.accel._contact is not ctx.accel._contact
        assert fresh.accel.geometric_normals is not ctx.accel.geometric_normals
        assert np.array_equal(render(edited, settings, context=fresh).image, render(edited, settings).image)
    # A light that moves the bounds by less than FRAME_SHIFT of their extent keeps embree's frame.
    kept = RenderContext(moved_light.validate(), reuse=ctx)
    assert not np.array_equal(kept.accel.bounds[1], ctx.accel.bounds[1])
    assert np.array_equal(kept.accel.center, ctx.accel.center)
    assert kept.accel._embree is ctx.accel._embree and kept.accel._contact is ctx.accel._contact
    assert kept.accel.geometric_normals is ctx.accel.geometric_normals
    image, reference = render(moved_light, settings, context=kept).image, render(moved_light, settings).image
    # (the same but where a path's spawn offsets, relative to the frame's centre, set it apart)
    assert np.mean(image == reference) > 0.5
    assert abs(image[..., :3].mean() / reference[..., :3].mean() - 1.0) < 0.01
    diffuse = RenderContext(dataclasses.replace(scene, materials=dataclasses.replace(
        scene.materials, dielectric_weight=glassless)).validate(), reuse=ctx)
    assert diffuse.accel._embree is ctx.accel._embree and diffuse.accel._contact is None


def _moved(scene, triangles, by):
    """``scene`` with the corners of ``triangles`` moved by ``by`` (3,)."""
    vertices = scene.vertices.copy()
    vertices[np.unique(scene.triangles[triangles])] += np.asarray(by, np.float32)
    return dataclasses.replace(scene, vertices=vertices).validate()


def _assert_hits_as_a_fresh_context(ctx, scene, old=None, mapped=False):
    """``ctx``'s tables, hits and contact hits (random rays, some with a limit, a quarter aimed at
    the moved triangles and a quarter at where ``old``, an earlier context, had them) are those of
    a fresh context of ``scene``; where two triangles meet a ray at the same distance (the edges of
    the subdivided triangles) either may be reported, at the same point, and a ray that went on
    past an old copy's box has its distance from there (float32's rounding of that point).  With
    ``mapped`` (rays mapped onto a moved object's earlier scene, ``Mover``: float32 rounds them
    otherwise) fewer distances are exact, and along a grazing ray a hit may lie farther along
    the surface: the distances are compared across it (times the cosine)."""
    fresh = RenderContext(scene)
    for name in ("v0", "e1", "e2", "area", "geometric_normals"):
        assert np.array_equal(getattr(ctx.accel, name), getattr(fresh.accel, name)), name
    rng = np.random.default_rng(5)
    lo, hi = fresh.accel.bounds
    o = rng.uniform(lo, hi, size=(100_000, 3))
    d = rng.normal(size=(100_000, 3))
    if ctx.accel._moved is not None:
        aim = rng.choice(ctx.accel._moved, 50_000)
        for rows, tables in ((slice(0, 25_000), ctx.accel), (slice(25_000, 50_000), old)):
            if tables is not None:
                at = aim[rows]
                d[rows] = tables.v0[at] + 0.3 * (tables.e1[at] + tables.e2[at]) - o[rows]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tmax = np.where(rng.random(100_000) < 0.5, rng.uniform(0.1, 2.0, 100_000), np.inf)
    a, b = ctx.accel.intersect(o, d, tmax), fresh.accel.intersect(o, d, tmax)
    assert np.array_equal(a.is_hit, b.is_hit)
    assert a.is_hit.sum() > 30_000
    h = np.flatnonzero(a.is_hit)
    cos = np.abs(np.einsum("ij,ij->i", d[h], fresh.accel.geometric_normals[b.prim_ids[h]])) if mapped else 1.0
    assert np.mean(a.t[h] == b.t[h]) > (0.8 if mapped else 0.98)
    assert (np.abs(a.t[h] - b.t[h]) * cos).max() < 1e-5 * fresh.accel.extent
    if ctx.accel._moved is not None:
        assert np.isin(a.prim_ids[h], ctx.accel._moved).sum() > 2_000
    same = a.prim_ids[h] == b.prim_ids[h]
    assert same.mean() > 0.95     # (the others: ties, as where a partly moved face overlaps its rest)
    pa, pb = (x.accel.hit_positions(y.prim_ids[h], y.b1[h], y.b2[h]) for x, y in ((ctx, a), (fresh, b)))
    assert (np.abs(pa - pb).max(axis=1) * cos).max() < 1e-5 * fresh.accel.extent
    # The contact scene (the non-glass triangles, which with_contacts probes): the same hits, and
    # the same triangles (indices among the non-glass ones) but for ties.
    if fresh.accel._contact is not None:
        assert np.array_equal(ctx.accel.contact_ids, fresh.accel.contact_ids)
        ca, cb = (x.accel._contact.run(np.ascontiguousarray(o - x.accel.center, np.float32),
                                       np.ascontiguousarray(d, np.float32), output=1) for x in (ctx, fresh))
        hit = cb["primID"] >= 0
        assert np.array_equal(ca["primID"] >= 0, hit) and hit.sum() > 30_000
        normals = fresh.accel.geometric_normals[fresh.accel.contact_ids[cb["primID"][hit]]]
        cos = np.abs(np.einsum("ij,ij->i", d[hit], normals)) if mapped else 1.0
        assert np.mean(ca["tfar"][hit] == cb["tfar"][hit]) > (0.8 if mapped else 0.98)
        assert (np.abs(ca["tfar"][hit] - cb["tfar"][hit]) * cos).max() < 1e-5 * fresh.accel.extent
        assert np.mean(ca["primID"] == cb["primID"]) > 0.95


def test_an_edit_that_moves_a_few_triangles_builds_theirs_alone():
    """``RenderContext(reuse=...)`` after an edit that moved a few triangles of the same mesh (an
    object dragged in the viewport): the earlier version's embree scenes are kept (the whole
    scene's and the contact scene's, ``SplitScene``), the moved triangles get scenes of their own
    and so do the triangles that reach into the box of their old copies (the floor under a box
    lifted off it: a ray that met the old bottom, in the floor's plane, must still meet the floor),
    and the triangle tables change in their rows; the context answers as a fresh one.  Moving some
    of them again keeps those scenes but the moved ones', an edited material keeps everything,
    moving triangles elsewhere adds a group of its own (the box's scenes kept), and moving over a
    quarter of the triangles builds one scene as before.  The render matches a fresh context's."""
    scene = subdivide(BUILTIN["glass_ceiling_room"](resolution=(16, 12)), 5)
    assert scene.triangle_count >= SPLIT_MIN_TRIANGLES
    lo, hi = scene.bounds()
    corners = scene.triangle_corners()
    box = np.flatnonzero(scene.material_ids == 3)             # (a box resting on the floor)
    assert corners[box][..., 2].min() == 0.0 and 0 < len(box) < 0.25 * scene.triangle_count
    inner = ((corners > lo + 0.05) & (corners < hi - 0.05)).all(axis=(1, 2))      # (the bounds stay)
    corner = np.flatnonzero(inner & (scene.material_ids == 0) & (corners[..., 0] < -1.5).all(axis=1)
                            & (corners[..., 2] > 2.4).all(axis=1))[:300]         # (of the ceiling)
    assert len(corner) == 300
    ctx = RenderContext(scene)
    lifted = _moved(scene, box, (0.0, 0.0, 0.3))
    split = RenderContext(lifted, reuse=ctx)
    for accel, base in ((split.accel._embree, ctx.accel._embree), (split.accel._contact, ctx.accel._contact)):
        assert isinstance(accel, SplitScene) and accel.base is base and accel.movers[0].scene is not None
        assert len(accel.patches) == 1 and accel.patches[0] is not None
    assert np.array_equal(split.accel._moved, box)
    floor = split.accel._groups[0][3]
    assert 0 < len(floor) < 1000 and (scene.material_ids[floor] == 1).any()
    _assert_hits_as_a_fresh_context(split, lifted, ctx.accel)
    # (part of the box again: the base and the patch kept)
    again = _moved(lifted, box[: len(box) // 2], (0.1, 0.0, 0.0))
    kept = RenderContext(again, reuse=split)
    for accel, earlier in ((kept.accel._embree, split.accel._embree),
                           (kept.accel._contact, split.accel._contact)):
        assert accel.base is earlier.base and accel.patches[0] is earlier.patches[0]
        assert accel.movers[0].scene is not earlier.movers[0].scene
    assert np.array_equal(kept.accel._moved, box)
    _assert_hits_as_a_fresh_context(kept, again, ctx.accel)
    colours = again.materials.diffuse_color.copy()
    colours[0] *= 0.5
    recoloured = dataclasses.replace(again, materials=dataclasses.replace(again.materials,
                                                                          diffuse_color=colours))
    same = RenderContext(recoloured, reuse=kept)
    assert same.accel._embree is kept.accel._embree and same.accel._contact is kept.accel._contact
    # (a corner of the ceiling: a second group, the box's kept)
    elsewhere = _moved(again, corner, (0.0, 0.0, -0.01))
    grouped = RenderContext(elsewhere, reuse=same)
    assert grouped.accel._embree.base is ctx.accel._embree
    assert grouped.accel._embree.patches[0] is kept.accel._embree.patches[0]
    assert grouped.accel._embree.movers[0] is kept.accel._embree.movers[0]
    assert [len(group[0]) for group in grouped.accel._groups] == [len(box), len(corner)]
    _assert_hits_as_a_fresh_context(grouped, elsewhere, ctx.accel)
    most = _moved(elsewhere, np.flatnonzero(inner), (0.0, 0.0, 0.01))
    whole = RenderContext(most, reuse=grouped)
    assert whole.accel._moved is None and not isinstance(whole.accel._embree, SplitScene)
    _assert_hits_as_a_fresh_context(whole, most)
    settings = RenderSettings(passes=3, **FAST)
    image = render(elsewhere, settings, context=grouped).image
    reference = render(elsewhere, settings).image
    assert np.isfinite(image).all()
    assert abs(image[..., :3].mean() / reference[..., :3].mean() - 1.0) < 0.01
    assert np.mean(np.abs(image - reference) < 1e-6) > 0.9


def _transformed(scene, triangles, matrix, by):
    """``scene`` with the corners of ``triangles`` turned by ``matrix`` (3, 3) about their centre and
    moved by ``by`` (3,), in float32 as Blender exports them."""
    vertices = scene.vertices.copy()
    ids = np.unique(scene.triangles[triangles])
    centre = vertices[ids].astype(np.float64).mean(axis=0)
    vertices[ids] = ((vertices[ids] - centre) @ np.asarray(matrix).T + centre + by).astype(np.float32)
    return dataclasses.replace(scene, vertices=vertices).validate()


def test_an_object_dragged_again_keeps_the_scenes_of_its_triangles():
    """An object moved again as a whole (moved, then turned and scaled: an affine map of its
    triangles each time) keeps the embree scenes its triangles got at the first move (``Mover``,
    the whole scene's and the contact scene's): the rays are mapped to where those scenes have
    them, and the context answers as a fresh one.  A vertex of it moved alone builds them again,
    and so does a turn whose corners are off an affine map by more than a quarter of the spawn
    offsets (as float32 rounds the corners of objects far from the origin: the scenes would no
    longer have them where the tables do)."""
    scene = subdivide(BUILTIN["glass_ceiling_room"](resolution=(16, 12)), 5)
    box = np.flatnonzero(scene.material_ids == 3)
    lifted = _moved(scene, box, (0.0, 0.0, 0.3))
    first = RenderContext(lifted, reuse=RenderContext(scene))
    c, s = np.cos(0.5), np.sin(0.5)
    turn = 1.2 * np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    moved = _moved(lifted, box, (0.1, 0.0, 0.0))
    turned = _transformed(moved, box, turn, (0.0, -0.05, 0.0))
    ctx = first
    for step in (moved, turned):
        ctx = RenderContext(step, reuse=ctx)
        for accel, built in ((ctx.accel._embree, first.accel._embree),
                             (ctx.accel._contact, first.accel._contact)):
            assert accel.movers[0].scene is built.movers[0].scene and accel.movers[0].back is not None
        _assert_hits_as_a_fresh_context(ctx, step, mapped=True)
    vertices = turned.vertices.copy()
    ids = np.unique(scene.triangles[box])
    rough = vertices.copy()
    rough[ids] += np.random.default_rng(1).uniform(-1e-4, 1e-4, (len(ids), 3)).astype(np.float32)
    bent = vertices.copy()
    bent[scene.triangles[box[0], 0]] += np.float32(0.05)
    for edited in (rough, bent):
        edited = dataclasses.replace(turned, vertices=edited).validate()
        rebuilt = RenderContext(edited, reuse=ctx)
        for accel, earlier in ((rebuilt.accel._embree, ctx.accel._embree),
                               (rebuilt.accel._contact, ctx.accel._contact)):
            assert accel.movers[0].scene is not earlier.movers[0].scene and accel.movers[0].back is None
        _assert_hits_as_a_fresh_context(rebuilt, edited)


def test_a_context_that_takes_the_earlier_ones_tables_answers_as_a_fresh_one():
    """``RenderContext(reuse=..., take=True)`` (the live server, which drops the earlier context):
    an edit that moves a few triangles changes the earlier context's tables in their rows instead
    of copying them, still finds their old copies' box, and answers as a fresh context; the earlier
    context, spent, is not reused (a later edit from it builds its scenes whole)."""
    scene = subdivide(BUILTIN["glass_ceiling_room"](resolution=(16, 12)), 5)
    box = np.flatnonzero(scene.material_ids == 3)
    ctx = RenderContext(scene)
    before = RenderContext(scene).accel
    lifted = _moved(scene, box, (0.0, 0.0, 0.3))
    taken = RenderContext(lifted, reuse=ctx, take=True)
    assert taken.accel.v0 is ctx.accel.v0 and taken.accel.geometric_normals is ctx.accel.geometric_normals
    assert isinstance(taken.accel._embree, SplitScene) and taken.accel._embree.base is ctx.accel._embree
    _assert_hits_as_a_fresh_context(taken, lifted, before)
    again = _moved(lifted, box, (0.1, 0.0, 0.0))
    rebuilt = RenderContext(again, reuse=ctx)
    assert rebuilt.accel._moved is None and not isinstance(rebuilt.accel._embree, SplitScene)
    _assert_hits_as_a_fresh_context(rebuilt, again)


def test_a_live_render_of_an_object_moved_twice_renders_as_a_fresh_context(live):
    """The live server through edits of a scene big enough to split (it takes each earlier
    context's tables): a box lifted, moved again, then a material edited; the last pass of each
    is the render of a fresh context but for rays at ties or past the box's old place."""
    scene = subdivide(BUILTIN["glass_ceiling_room"](resolution=(16, 12)), 5)
    box = np.flatnonzero(scene.material_ids == 3)
    lifted = _moved(scene, box, (0.0, 0.0, 0.3))
    again = _moved(lifted, box, (0.1, 0.0, 0.0))
    colours = again.materials.diffuse_color.copy()
    colours[3] = (0.8, 0.2, 0.1)
    recoloured = dataclasses.replace(again, materials=dataclasses.replace(again.materials,
                                                                          diffuse_color=colours))
    settings = RenderSettings(passes=2, **FAST)
    for edited in (scene, lifted, again, recoloured):
        live.start(edited, settings)
        seen = wait(live, lambda s: bool(s) and s[-1][1]["pass"] == 2)
        image, reference = seen[-1][0], render(edited, settings).image
        assert np.isfinite(image).all()
        assert abs(image[..., :3].mean() / reference[..., :3].mean() - 1.0) < 0.01
        assert np.mean(np.abs(image - reference) < 1e-6) > 0.9


def test_rays_past_the_old_places_of_two_moved_objects_meet_what_lies_behind():
    """Two blocks in a row before a wall, moved aside one edit after the other: their old copies lie
    in two boxes apart (two groups of ``SplitScene``), and rays along the row, from in front of the
    blocks and from inside the first one's old place, pass both (a round a box) to the wall, or stop
    at their limit; rays from the side meet the blocks where they are now."""
    m = MeshBuilder()
    m.add_quad((-2, 6, -1), (2, 6, -1), (2, 6, 2), (-2, 6, 2), 0)                  # (the wall, facing -y)
    m.add_box((-0.3, 0.7, 0.2), (0.3, 1.3, 0.8), 0)
    m.add_box((-0.3, 2.7, 0.2), (0.3, 3.3, 0.8), 0)
    for x0 in np.arange(-2.0, 2.0, 0.5):                                    # (a floor well below)
        for y0 in np.arange(-2.0, 6.0, 1.0):
            m.add_quad((x0, y0, -1), (x0 + 0.5, y0, -1), (x0 + 0.5, y0 + 1, -1), (x0, y0 + 1, -1), 0)
    scene = subdivide(m.build(Materials.build([{"name": "grey", "diffuse": (0.5, 0.5, 0.5)}])), 4)
    assert scene.triangle_count >= SPLIT_MIN_TRIANGLES
    corners = scene.triangle_corners()
    blocks = [np.flatnonzero(((np.abs(corners[..., 1] - y) < 0.31) & (corners[..., 2] > 0.0)).all(axis=1))
              for y in (1.0, 3.0)]
    ctx = RenderContext(scene)
    first = _moved(scene, blocks[0], (1.0, 0.0, 0.0))
    second = _moved(first, blocks[1], (-1.0, 0.0, 0.0))
    split = RenderContext(second, reuse=RenderContext(first, reuse=ctx))
    assert split.accel._embree.base is ctx.accel._embree and len(split.accel._groups) == 2
    fresh = RenderContext(second)
    rng = np.random.default_rng(2)
    n = 4000
    o = np.column_stack([rng.uniform(-0.25, 0.25, n), np.where(np.arange(n) % 2, -1.0, 1.0),
                         rng.uniform(0.25, 0.75, n)])
    d = np.tile([0.0, 1.0, 0.0], (n, 1))
    d[:, 0] = rng.uniform(-0.01, 0.01, n)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tmax = np.where(np.arange(n) % 4 < 2, np.inf, rng.uniform(1.5, 8.0, n))
    a, b = split.accel.intersect(o, d, tmax), fresh.accel.intersect(o, d, tmax)
    assert np.array_equal(a.is_hit, b.is_hit) and np.array_equal(a.prim_ids, b.prim_ids)
    assert np.allclose(a.t[a.is_hit], b.t[b.is_hit], rtol=0, atol=1e-5)
    wall = a.is_hit & (scene.triangle_corners()[np.maximum(a.prim_ids, 0), 0, 1] == 6.0)
    assert wall.sum() > n // 2 and (a.is_hit == (tmax > 6.0 - o[:, 1])).all()
    side = np.column_stack([np.full(n, -3.0), rng.uniform(0.8, 3.2, n), rng.uniform(0.25, 0.75, n)])
    toward = np.tile([1.0, 0.0, 0.0], (n, 1))
    a, b = split.accel.intersect(side, toward), fresh.accel.intersect(side, toward)
    assert np.array_equal(a.prim_ids, b.prim_ids) and np.isin(a.prim_ids, blocks[0]).sum() > n // 10


@pytest.mark.parametrize("perspective", [True, False], ids=["perspective", "orthographic"])
def test_a_camera_from_opengl_matrices_sees_what_they_project(perspective):
    """``Camera.from_view``: the frame and clip range of an OpenGL projection, the camera's pose
    from the inverse view matrix; an orthographic near plane behind the view's origin moves the
    ray origins back to it (clip_start 0)."""
    rng = np.random.default_rng(3)
    pose = Camera.look_at((1.0, -4.0, 2.0), (0.2, 0.3, 0.5)).world_from_camera
    view = np.linalg.inv(pose)
    left, right, bottom, top = -0.5, 0.7, -0.3, 0.4
    if perspective:
        n, f = 0.1, 80.0
        p = np.array([[2 * n / (right - left) / n, 0, (right + left) / (right - left), 0],
                      [0, 2 * n / (top - bottom) / n, (top + bottom) / (top - bottom), 0],
                      [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)], [0, 0, -1, 0]])
    else:
        n, f = -20.0, 20.0
        p = np.array([[2 / (right - left), 0, 0, -(right + left) / (right - left)],
                      [0, 2 / (top - bottom), 0, -(top + bottom) / (top - bottom)],
                      [0, 0, -2 / (f - n), -(f + n) / (f - n)], [0, 0, 0, 1]])
    cam = Camera.from_view(view, p, perspective, (40, 30))
    np.testing.assert_allclose(cam.frame, (left, right, bottom, top), atol=1e-12)
    if perspective:
        np.testing.assert_allclose((cam.clip_start, cam.clip_end), (n, f), rtol=1e-9)
        np.testing.assert_allclose(cam.world_from_camera, pose, atol=1e-12)
    else:
        assert cam.clip_start == 0.0 and cam.clip_end == pytest.approx(f - n)
        np.testing.assert_allclose(cam.world_from_camera[:3, 3], pose[:3, 3] - n * pose[:3, 2], atol=1e-12)
    # The camera's rays through pixel centres: their points project to those pixels' centres.
    w, h = cam.resolution
    pix = rng.integers(0, w * h, 25)
    origins, dirs, _, _ = generate_camera_rays(cam, pix, np.full((25, 4), 0.5))
    points = origins + dirs * rng.uniform(0.5, 10.0, 25)[:, None]
    clip = np.column_stack([points, np.ones(25)]) @ view.T @ p.T
    want = np.column_stack([(pix % w + 0.5) / w * 2 - 1, 1 - (pix // w + 0.5) / h * 2])
    np.testing.assert_allclose(clip[:, :2] / clip[:, 3:], want, atol=1e-9)
    with pytest.raises(ValueError, match="degenerate"):
        Camera.from_view(view, np.zeros((4, 4)), True, (40, 30))

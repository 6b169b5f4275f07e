"""Rigid objects of a labelling scene: the spec format, validation, rigid bodies from selected markers."""

import json

import numpy as np
import pytest

from core.errors import InputError
from core.io import Take
from core.labeling import label_scene, labelling_accuracy, load_scene_spec, rigid_body_from_points, save_scene_spec
from core.labeling.models import kabsch_kernel
from core.simulate import scene_objects, simulate_scene


def test_spec_round_trip_and_shapes(tmp_path):
    objects = scene_objects(3)
    path = tmp_path / "spec.json"
    save_scene_spec(objects, path)
    loaded = load_scene_spec(path)
    assert [(spec.name, spec.kind) for spec in loaded] == [("box", "box"), ("cup", "cylinder"), ("ball", "sphere")]
    for original, again in zip(objects, loaded, strict=True):
        assert original.marker_names == again.marker_names
        assert np.allclose(original.marker_positions, again.marker_positions)
        assert again.surface_distance(again.marker_positions).max() < 10.0
    assert np.allclose(loaded[0].box_extents(), [90, 60, 40])
    assert np.allclose(loaded[1].box_extents(), [70, 70, 100])


@pytest.mark.parametrize("entry, message", [
    ({"name": "c", "type": "cone", "markers": {}}, "unknown type"),
    ({"name": "c", "type": "rigid", "markers": {"a": [0, 0, 0], "b": [1, 0, 0]}}, "at least 3"),
    ({"name": "c", "type": "rigid", "markers": {"a": [0, 0, 0], "b": [10, 0, 0], "c": [20, 0, 0]}}, "collinear"),
    ({"name": "c", "type": "sphere", "radius_mm": 30, "markers": {"a": [0, 0, 200], "b": [30, 0, 0],
                                                                  "c": [0, 30, 0]}}, "from the sphere"),
    ({"name": "c", "type": "box", "markers": {"a": [0, 0, 10], "b": [10, 0, 0], "c": [0, 10, 0]}}, "size_mm"),
    ({"name": "c", "type": "cylinder", "radius_mm": -1, "height_mm": 5,
      "markers": {"a": [0, 0, 10], "b": [10, 0, 0], "c": [0, 10, 0]}}, "positive"),
    ({"name": "c", "type": "rigid", "markers": {"a": [0, "x", 0], "b": [10, 0, 0], "c": [0, 10, 0]}}, "numbers"),
])
def test_bad_object_entries(tmp_path, entry, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"objects": [entry]}))
    with pytest.raises(InputError, match=message):
        load_scene_spec(path)


def test_bad_spec_files(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text('{"things": []}')
    with pytest.raises(InputError, match="objects"):
        load_scene_spec(path)
    entry = {"name": "c", "type": "rigid", "markers": {"a": [0, 0, 0], "b": [10, 0, 0], "c": [0, 10, 0]}}
    path.write_text(json.dumps({"objects": [entry, entry]}))
    with pytest.raises(InputError, match="named"):
        load_scene_spec(path)


def test_rigid_body_from_selected_markers_is_tracked():
    scene = simulate_scene("glove-13", n_frames=150, seed=2, hands="right", n_objects=2)
    names = list(scene.truth["marker_names"])
    cup = [names.index(name) for name in ("cup1", "cup2", "cup3", "cup4")]
    body = rigid_body_from_points("mug", ["cup1", "cup2", "cup3", "cup4"], scene.truth["marker_positions"][0, cup])
    assert body.kind == "rigid" and np.allclose(body.marker_positions.mean(axis=0), 0.0)
    objects = [scene.objects[0], body]
    result = label_scene(scene.take, "right", "glove-13", objects=objects)
    accuracy = labelling_accuracy(result, scene.truth["point_marker"])
    assert accuracy["correct_share"] >= 0.995 and accuracy["ghost_labelled_share"] < 0.005, accuracy
    assert [model.kind for model in result.models] == ["right", "object", "object"]


def test_object_only_take_and_selected_markers_must_be_present():
    scene = simulate_scene("dense", n_frames=60, seed=3, hands="right", n_objects=2)
    owner = scene.truth["model_of_marker"]
    truth = scene.truth["point_marker"]
    objects_only = (truth >= 0) & (owner[np.maximum(truth, 0)] > 0)
    positions = np.where(objects_only[:, :, None], scene.take.marker_positions, np.nan)
    take = Take(scene.take.marker_names, positions, 100.0)
    result = label_scene(take, "right", "dense", objects=scene.objects)
    assert result.models[0].init_frame == -1 and result.models[1].init_frame == 0
    with pytest.raises(InputError, match="present"):
        rigid_body_from_points("x", ["a", "b", "c"], np.array([[0.0, 0, 0], [1, 0, 0], [np.nan, 0, 0]]))


def test_compiled_kabsch_matches_the_svd_solution():
    rng = np.random.default_rng(1)
    source = rng.normal(size=(5, 3)) * 40.0
    angle = 2.5
    rotation = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    target = source @ rotation.T + [100.0, -20.0, 5.0]
    found, translation = kabsch_kernel(source, target)
    assert np.allclose(found, rotation, atol=1e-9) and np.allclose(translation, [100, -20, 5], atol=1e-7)
    planar = source.copy()
    planar[:, 2] = 0.0
    found, _ = kabsch_kernel(planar[:3], planar[:3] @ rotation.T)
    assert np.allclose(found, rotation, atol=1e-9)

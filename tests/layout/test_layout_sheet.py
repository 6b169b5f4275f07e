"""Placement sheets: what they show (core, no Qt) and the A4 PNG/PDF files (painted off screen)."""

import datetime

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.layout.placement_sheet import placement_sheet, rasterise_view, segment_marker_names
from handmocap.core.model import MarkerLayout, MarkerSpec, load_layout, load_template


@pytest.fixture(scope="module")
def model():
    return load_template()


@pytest.fixture(scope="module")
def sheet(model):
    return placement_sheet(model, load_layout("glove-13"), date=datetime.date(2026, 3, 1))


def test_sheet_lists_every_marker_with_its_segment(sheet):
    assert sheet.title == "Marker placement: glove-13" and sheet.date == "2026-03-01"
    assert [row.number for row in sheet.rows] == list(range(1, 14))
    rows = {row.name: row for row in sheet.rows}
    assert rows["index_tip"].segment == "index distal phalanx"
    assert rows["thumb_middle"].segment == "thumb proximal phalanx"
    assert rows["hand_top"].segment == "back of the hand"
    assert "mm distal of the DIP joint" in rows["index_tip"].location


def test_back_view_is_not_mirrored_and_shows_the_markers(model, sheet):
    back, side = sheet.views
    thumb = [row.number - 1 for row in sheet.rows if row.name == "thumb_tip"][0]
    little = [row.number - 1 for row in sheet.rows if row.name == "little_tip"][0]
    # a right hand seen from its back: thumb on the left, little finger on the right, fingers up
    assert back.markers[thumb, 0] < back.markers[little, 0]
    tips = [row.number - 1 for row in sheet.rows if row.name.endswith("_tip")]
    backs = [row.number - 1 for row in sheet.rows if row.name.startswith("hand_")]
    assert back.markers[tips, 1].min() > back.markers[backs, 1].max()
    assert back.visible[backs].all()
    # from the thumb side the little finger's markers are hidden behind the other fingers
    assert not side.visible[[row.number - 1 for row in sheet.rows if row.name == "little_middle"][0]]
    assert len(back.faces) < len(model.faces)           # back faces culled


def test_rasterised_skin_covers_the_hand_silhouette(sheet):
    back = sheet.views[0]
    image, origin = rasterise_view(back, pixels_per_mm=2.0, scale=0.5)
    inside = np.isfinite(image)
    assert 0.2 < inside.mean() < 0.8
    assert (image[inside] > 0.2).all() and (image[inside] <= 1.0).all()
    # the back-of-hand marker falls on skin
    column = round((origin[0] + 0.5 * back.markers[0, 0]) * 2.0)
    row = round((origin[1] - 0.5 * back.markers[0, 1]) * 2.0)
    assert inside[row, column]


def test_segment_names_are_unique_per_segment(model):
    layout = load_layout("glove-13")
    from handmocap.core.model import resolve_layout

    vertices = resolve_layout(model, layout).vertex
    names = segment_marker_names(model, np.concatenate([vertices, vertices[:2]]))
    assert len(set(names)) == len(names)
    assert names[0] == "hand_back" and names[-2] == "hand_back_4"


def test_png_and_pdf_are_written(tmp_path, sheet):
    from handmocap.widgets.placement_sheet import render_sheet_image, save_placement_sheet

    png = save_placement_sheet(sheet, tmp_path / "sheet.png", dpi=100)
    pdf = save_placement_sheet(sheet, tmp_path / "sheet.pdf")
    assert png.stat().st_size > 30_000 and pdf.read_bytes()[:5] == b"%PDF-" and pdf.stat().st_size > 20_000
    image = render_sheet_image(sheet, dpi=60)
    assert (image.width(), image.height()) == (round(210 / 25.4 * 60), round(297 / 25.4 * 60))
    # the middle of the page (the back view) is skin-coloured, not blank
    colors = {image.pixelColor(x, image.height() // 3).name() for x in range(0, image.width(), 4)}
    assert len(colors) > 10
    assert not list(tmp_path.glob("*.tmp*"))


def test_bad_sheet_paths_are_input_errors(tmp_path, sheet):
    from handmocap.widgets.placement_sheet import save_placement_sheet

    with pytest.raises(InputError, match=".png or .pdf"):
        save_placement_sheet(sheet, tmp_path / "sheet.svg")
    with pytest.raises(InputError, match="does not exist"):
        save_placement_sheet(sheet, tmp_path / "missing" / "sheet.png")


def test_a_long_layout_still_fits_the_page(model, tmp_path):
    from handmocap.widgets.placement_sheet import save_placement_sheet

    dense = load_layout("dense")
    long = MarkerLayout("long", dense.markers + tuple(MarkerSpec(f"{spec.name}_b", vertex=100 + index)
                                                      for index, spec in enumerate(dense.markers[:6])), "x" * 400)
    sheet = placement_sheet(model, long)
    assert len(sheet.rows) == 30 and sheet.subtitle.endswith("…")
    assert save_placement_sheet(sheet, tmp_path / "long.png", dpi=60).exists()


def boxes_overlap(a: np.ndarray, b: np.ndarray, half: np.ndarray) -> bool:
    return bool((np.abs(a - b) < 2.0 * half).all())


def test_numbers_overlap_neither_each_other_nor_markers():
    from handmocap.core.layout.label_placement import place_labels

    # the thumb-side view of the dense layout: markers along the finger's edge, 1-3 mm apart
    side = placement_sheet(load_template(), load_layout("dense")).views[1]
    anchors = side.markers * np.array([0.5, -0.5])                   # page mm at 1:2, y down
    labelled = side.visible.copy()
    size, radius = (5.6, 4.6), 2.4
    labels = place_labels(anchors, labelled, anchors.mean(axis=0), size, radius)
    assert np.isnan(labels[~labelled]).all() and np.isfinite(labels[labelled]).all()
    half = np.array(size) / 2.0
    placed = labels[labelled]
    for i in range(len(placed)):
        for j in range(i + 1, len(placed)):
            assert not boxes_overlap(placed[i], placed[j], half), (i, j)
    nearest = np.clip(anchors[None], placed[:, None] - half, placed[:, None] + half)
    assert (np.linalg.norm(nearest - anchors[None], axis=2) > radius).all()
    assert (np.linalg.norm(placed - anchors[labelled], axis=1) <= 16.0).all()   # near their marker


def test_a_lone_marker_is_numbered_straight_outward():
    from handmocap.core.layout.label_placement import place_labels

    labels = place_labels(np.array([[10.0, 0.0]]), np.array([True]), np.zeros(2), (5.0, 4.0), 2.0)
    np.testing.assert_allclose(labels[0], [15.0, 0.0])


def test_pdf_adds_the_back_of_the_hand_at_full_scale(tmp_path, sheet):
    import re

    from handmocap.widgets.placement_sheet import render_sheet_image, save_placement_sheet

    pdf = save_placement_sheet(sheet, tmp_path / "sheet.pdf").read_bytes()
    assert len(re.findall(rb"/Type\s*/Page\b(?!s)", pdf)) == 2
    dpi = 100
    image = render_sheet_image(sheet, dpi=dpi, full_scale=True)
    pixels = np.frombuffer(image.constBits(), np.uint8).reshape(image.height(), image.width(), 4)
    blue, green, red = (pixels[..., channel].astype(int) for channel in range(3))
    skin = (red - blue > 12) & (red >= green) & (green >= blue)           # shaded skin, not paper or ink
    rows = np.flatnonzero(skin.any(axis=1))
    back = sheet.views[0]
    drawn_mm = (rows[-1] - rows[0] + 1) * 25.4 / dpi
    assert drawn_mm == pytest.approx(back.bounds[3] - back.bounds[1], abs=1.5)     # 1:1 on paper

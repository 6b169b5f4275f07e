"""``handmocap layout sheet`` / ``layout table`` / ``layout optimize`` options and their error messages."""

import json

from handmocap.app.cli.main import main


def test_layout_sheet_writes_png_and_pdf(tmp_path, capsys):
    for name in ("sheet.png", "sheet.pdf"):
        assert main(["layout", "sheet", "grasp-4", "--out", str(tmp_path / name)]) == 0
        assert (tmp_path / name).stat().st_size > 20_000
    assert "grasp-4" in capsys.readouterr().out
    assert main(["layout", "sheet", "grasp-4", "--out", str(tmp_path / "sheet.svg")]) == 2
    assert "written as .png or .pdf" in capsys.readouterr().err
    assert main(["layout", "sheet", "no-such-layout", "--out", str(tmp_path / "x.png")]) == 2
    assert "unknown layout" in capsys.readouterr().err


def test_layout_table_json(capsys):
    assert main(["layout", "table", "--counts", "4", "5", "--particles", "30", "--iterations", "3",
                 "--frames", "40", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert [row["markers"] for row in figures["rows"]] == [4, 5]
    assert figures["specific"] == "grasps" and figures["generic"] == "gestures"
    for row in figures["rows"]:
        assert 0 < row["specific_mean_mm"] <= row["specific_max_mm"]
        assert 0 < row["generic_mean_mm"] <= row["generic_max_mm"]


def test_layout_optimize_names_and_bad_input(tmp_path, capsys):
    out = tmp_path / "tiny.json"
    assert main(["layout", "optimize", "--markers", "5", "--particles", "40", "--iterations", "3", "--keyframes", "3",
                 "--name", "tiny", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["name"] == "tiny" and len(data["markers"]) == 5 and "pso" in data["description"]
    capsys.readouterr()
    assert main(["layout", "optimize", "--markers", "2", "--dims", "6", "--out", str(out), "--overwrite"]) == 2
    assert "cannot constrain" in capsys.readouterr().err
    assert main(["layout", "optimize", "--markers", "6", "--motions", str(tmp_path / "none.npz"),
                 "--out", str(out), "--overwrite"]) == 2
    assert "none.npz" in capsys.readouterr().err
    assert main(["layout", "optimize", "--markers", "6", "--particles", "0", "--out", str(out), "--overwrite"]) == 2
    assert "particle" in capsys.readouterr().err
    assert json.loads(out.read_text())["name"] == "tiny"          # a failed run left the earlier file alone

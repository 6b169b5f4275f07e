"""``handmocap layout optimise`` is the command; ``layout optimize`` stays as its alias so scripts keep working."""

import pytest

from handmocap.app.cli.layout import command_layout_optimise
from handmocap.app.cli.main import build_parser


def test_optimise_and_its_american_alias_run_the_same_command(capsys):
    parser = build_parser()
    for spelling in ("optimise", "optimize"):
        args = parser.parse_args(["layout", spelling, "--markers", "6", "--out", "layout.json"])
        assert args.handler is command_layout_optimise and args.markers == 6
    with pytest.raises(SystemExit):
        parser.parse_args(["layout", "--help"])
    assert "optimise (optimize)" in capsys.readouterr().out

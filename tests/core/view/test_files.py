"""``view`` reads a run folder's pictures only as regular PNG files reached with no symlink anywhere below
the run folder, and says why one that is there was left out (for the page)."""

from __future__ import annotations

from pathlib import Path

from safeembodai_core.view.files import PNG, read_run_file


def test_a_picture_through_a_symlinked_folder_is_left_out_with_why(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "t.png").write_bytes(PNG + b"TOP-SECRET")
    run = tmp_path / "run"
    run.mkdir()
    (run / "trajectories").symlink_to(outside)
    (run / "figures").mkdir()
    (run / "figures" / "real.png").write_bytes(PNG + b"mine")
    (run / "figures" / "text.png").write_bytes(b"not a picture")
    left_out: list[str] = []
    assert read_run_file(run / "trajectories" / "t.png", png=True, folder=run, left_out=left_out) is None
    assert read_run_file(run / "figures" / "real.png", png=True, folder=run, left_out=left_out) == PNG + b"mine"
    assert read_run_file(run / "figures" / "text.png", png=True, folder=run, left_out=left_out) is None
    assert read_run_file(run / "figures" / "none.png", png=True, folder=run, left_out=left_out) is None  # absent
    assert left_out == ["trajectories/t.png: trajectories is a symlink (not followed)",
                        "figures/text.png: not a PNG"]
    assert read_run_file(Path(outside / "t.png"), png=True) == PNG + b"TOP-SECRET"  # the file itself is fine

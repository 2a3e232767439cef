"""``twoscale cache``: list each cache (folder, entries, size) and clear all or one."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale.caches import caches
from twoscale.cli.main import main
from twoscale.io.cache_entry import write_entry


@pytest.fixture
def cache_root(tmp_path, monkeypatch):
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path))
    block = write_entry(tmp_path / "block-0123.npz", {"fields": np.zeros((50, 40))})
    laws = sum(write_entry(tmp_path / "surface-laws" / f"k-{i}.npz", {"P": np.ones(5)}) for i in range(3))
    (tmp_path / "notes.txt").write_text("the user's own file")
    return tmp_path, block, laws


def _rows(out: str) -> dict:
    lines = out.strip().splitlines()
    assert lines[0].split()[:4] == ["cache", "folder", "entries", "size"]
    return {line.split()[0]: line.split() for line in lines[1:]}


def test_list_gives_each_cache_its_folder_entries_and_size(cache_root, capsys):
    root, block, laws = cache_root
    assert main(["cache"]) == 0
    rows = _rows(capsys.readouterr().out)
    assert set(rows) == {"block-corrections", "surface-laws"}
    assert rows["block-corrections"][1:3] == [str(root), "1"]
    assert rows["surface-laws"][1:3] == [str(root / "surface-laws"), "3"]
    sizes = {c.name: c.size() for c in caches()}
    assert sizes == {"block-corrections": block, "surface-laws": laws}
    assert rows["block-corrections"][3] == f"{block / 1e3:.3g}"
    assert rows["surface-laws"][3] == f"{laws / 1e3:.3g}"


def test_clear_one_cache_then_all_leaves_other_files(cache_root, capsys):
    root, block, laws = cache_root
    assert main(["cache", "clear", "surface-laws"]) == 0
    assert "3 entries" in capsys.readouterr().out
    assert list((root / "surface-laws").iterdir()) == []
    assert (root / "block-0123.npz").exists()
    assert main(["cache", "clear"]) == 0
    assert not (root / "block-0123.npz").exists() and (root / "notes.txt").exists()
    capsys.readouterr()
    assert main(["cache", "list"]) == 0
    rows = _rows(capsys.readouterr().out)
    assert rows["block-corrections"][2] == rows["surface-laws"][2] == "0"


def test_unknown_cache_name_is_one_line_exit_2(cache_root, capsys):
    assert main(["cache", "clear", "everything"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "everything" in err[0]


@pytest.mark.parametrize("action", [[], ["clear"]])
def test_cache_root_that_is_a_file_is_one_line_exit_2(tmp_path, monkeypatch, capsys, action):
    root = tmp_path / "cache-file"
    root.write_text("not a folder")
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(root))
    assert main(["cache", *action]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: block-corrections: ") and str(root) in err[0]
    assert root.read_text() == "not a folder"

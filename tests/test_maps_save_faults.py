"""Saving a map over an old one, killed at every step: the old map or the new one loads, never neither.

The save runs in a forked child whose k-th file-system change (rename, replace, link, unlink)
ends the process on the spot (``os._exit``, as a power cut or SIGKILL would), for every k until
the save gets through. The parent then finds the map complete, before and after the start-up
cleanup (``MapCatalogue.remove_leftovers``, as cli runs it), and a new save over it works.
Real files in a temporary folder; the real catalogue and map files.
"""

import multiprocessing
import os

import pytest

from flask_move_server.maps import mapfile
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.mapfile import Grid

OLD = Grid(4, 3, 0.05, -1.0, -2.0, bytes([0] * 12))  # all free
NEW = Grid(5, 2, 0.10, 0.0, 0.0, bytes([100] * 10))  # all occupied, another size
STEPS = ("rename", "replace", "link", "unlink")
KILLED = 17


def _save_killed_at(folder, step, name, overwrite):
    """In the child: the ``step``-th file-system change exits the process before it happens."""
    count = [0]

    def deadly(real):
        def call(*args, **kwargs):
            count[0] += 1
            if count[0] == step:
                os._exit(KILLED)
            return real(*args, **kwargs)
        return call

    for op in STEPS:
        setattr(os, op, deadly(getattr(os, op)))
    MapCatalogue(folder).save(name, NEW, overwrite=overwrite)
    os._exit(0)


def killed_save(folder, step, name="flat", overwrite=True):
    """Run the save in a forked child killed at ``step``; True when it finished before that step."""
    child = multiprocessing.get_context("fork").Process(target=_save_killed_at, args=(folder, step, name, overwrite))
    child.start()
    child.join(30)
    assert child.exitcode in (0, KILLED), child.exitcode
    return child.exitcode == 0


def which(maps, name="flat"):
    """"old" or "new": the version of the map that loads, whole (a broken map fails the test)."""
    info = maps.describe(name)
    assert info.problem is None, info.problem
    grid = maps.load(name)
    for label, want in (("old", OLD), ("new", NEW)):
        if (grid.width, grid.height, grid.resolution, grid.cells) == (want.width, want.height, want.resolution,
                                                                        want.cells):
            return label
    pytest.fail("the map loads as neither version: {} x {}".format(grid.width, grid.height))


def overwrite_killed_at_every_step(tmp_path, prepare):
    seen, step = [], 1
    while True:
        folder = str(tmp_path / "run{}".format(step))
        maps = MapCatalogue(folder)
        prepare(maps)
        done = killed_save(folder, step)
        before = which(maps)
        maps.remove_leftovers()  # what cli does at start-up
        assert which(maps) == before
        assert [m.name for m in maps.list()] == ["flat"]
        maps.save("flat", OLD, overwrite=True)  # the next save over it works, and tidies
        assert which(maps) == "old" and maps.leftovers() == []
        seen.append(before)
        if done:
            return seen
        step += 1
        assert step < 50, "the save never finished"


def test_an_overwrite_killed_at_any_step_leaves_the_old_or_the_new_map(tmp_path):
    seen = overwrite_killed_at_every_step(tmp_path, lambda maps: maps.save("flat", OLD))
    assert seen[0] == "old" and seen[-1] == "new" and len(seen) > 3


def test_a_save_over_what_an_interrupted_save_left_is_safe_at_any_step_and_tidies(tmp_path):
    def interrupted(maps):
        maps.save("flat", OLD)
        killed_save(maps.folder, 2)  # the YAML names the new image under its temporary name now
        image = mapfile.named_image(maps.yaml_path("flat"))
        assert mapfile.is_part(image) and maps.leftovers() == [], image
        assert which(maps) == "new"

    assert set(overwrite_killed_at_every_step(tmp_path, interrupted)) == {"new"}


def test_deleting_a_map_an_interrupted_save_left_leaves_no_file_behind(tmp_path):
    maps = MapCatalogue(str(tmp_path / "maps"))
    maps.save("flat", OLD)
    killed_save(maps.folder, 3)
    maps.delete("flat")
    maps.remove_leftovers()
    assert os.listdir(maps.folder) == []


def test_a_new_map_killed_at_any_step_is_absent_or_whole(tmp_path):
    step = 1
    while True:
        folder = str(tmp_path / "run{}".format(step))
        maps = MapCatalogue(folder)
        done = killed_save(folder, step, name="fresh", overwrite=False)
        maps.remove_leftovers()
        listed = maps.list()
        assert listed == [] or (listed[0].problem is None and maps.load("fresh").width == NEW.width)
        assert maps.leftovers() == []
        if done:
            assert [m.name for m in listed] == ["fresh"]
            return
        step += 1
        assert step < 50


def test_an_overwrite_works_in_a_folder_without_hard_links(tmp_path, monkeypatch):
    def no_links(*args, **kwargs):
        raise PermissionError(1, "Operation not permitted")  # what FAT and exFAT answer

    maps = MapCatalogue(str(tmp_path / "maps"))
    maps.save("flat", OLD)
    monkeypatch.setattr(os, "link", no_links)
    maps.save("flat", NEW, overwrite=True)
    assert which(maps) == "new" and maps.leftovers() == []
    assert sorted(os.listdir(maps.folder)) == ["flat.pgm", "flat.yaml"]


def test_renaming_a_map_an_interrupted_save_left_takes_its_image_along_and_leaves_nothing(tmp_path):
    maps = MapCatalogue(str(tmp_path / "maps"))
    maps.save("flat", OLD)
    killed_save(maps.folder, 4)  # the YAML names the new image's temporary; flat.pgm is new too
    maps.rename("flat", "home")
    maps.remove_leftovers()
    assert sorted(os.listdir(maps.folder)) == ["home.pgm", "home.yaml"]
    assert which(maps, "home") == "new"

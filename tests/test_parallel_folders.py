"""Two parallel shots writing into one new folder (``make_folders``), replayed step by step in two
threads: shot A makes the folder and fails, shot B had found it made (so not B's to remove) and
claims its output only after A's cleanup removed the folder again. B's claim said the folder does
not exist; B now makes it again, and what B does not commit is removed as before."""

from __future__ import annotations

import threading

import pytest

from usdgaze.errors import UsdGazeError
from usdgaze.files.transaction import Outputs


def _race(folder, b_fails: bool) -> list[str]:
    said: list[str] = []
    a_made, b_checked = threading.Event(), threading.Event()

    def shot_a():
        try:
            with Outputs() as tx:
                tx.make_folder(folder)
                tx.claim(folder / "a.usda", "--out")
                a_made.set()
                b_checked.wait(30)
                raise UsdGazeError("a.usda: shot A fails")
        except UsdGazeError as exc:
            said.append(f"A: {exc}")
        finally:
            a_made.set()

    def shot_b():
        a_made.wait(30)
        try:
            with Outputs() as tx:
                tx.make_folder(folder)  # there: A made it
                b_checked.set()
                a.join(30)  # A has failed and removed it
                tx.claim(folder / "b.usda", "--out")
                tx.stage_text(folder / "b.usda", "shot B")
                if b_fails:
                    raise UsdGazeError("b.usda: shot B fails")
            said.append("B: ok")
        except UsdGazeError as exc:
            said.append(f"B: {exc}")
        finally:
            b_checked.set()

    a, b = threading.Thread(target=shot_a), threading.Thread(target=shot_b)
    a.start()
    b.start()
    b.join(60)
    return said


@pytest.mark.parametrize("deep", [False, True])
def test_a_folder_removed_by_a_parallel_shots_cleanup_is_made_again(tmp_path, deep):
    folder = tmp_path / "new" / "deeper" if deep else tmp_path / "new"
    said = _race(folder, b_fails=False)
    assert said == ["A: a.usda: shot A fails", "B: ok"], said
    assert sorted(p.name for p in folder.iterdir()) == ["b.usda"]  # no temporaries, nothing of A's
    assert (folder / "b.usda").read_bytes() == b"shot B"


def test_the_folder_made_again_goes_when_that_shot_fails_too(tmp_path):
    said = _race(tmp_path / "new", b_fails=True)
    assert said == ["A: a.usda: shot A fails", "B: b.usda: shot B fails"], said
    assert list(tmp_path.iterdir()) == []


def test_a_folder_removed_between_the_claims_check_and_the_temporary_is_made_again(tmp_path, monkeypatch):
    """The same cleanup landing after B's claim found the folder but before B's temporary is in it."""
    from usdgaze.files import transaction

    folder = tmp_path / "new"
    folder.mkdir()
    swept = transaction.sweep

    def then_removed(where):  # runs just before the temporary folder is made
        swept(where)
        folder.rmdir()
        monkeypatch.setattr(transaction, "sweep", swept)

    with Outputs() as tx:
        tx.make_folder(folder)
        monkeypatch.setattr(transaction, "sweep", then_removed)
        tx.claim(folder / "b.usda", "--out")
        tx.stage_text(folder / "b.usda", "shot B")
    assert sorted(p.name for p in folder.iterdir()) == ["b.usda"]

"""Real two-person takes as HHI training pairs (data/two_person_pairs.py): both people as egos, each with the other
as its partner in the take's own world, read by the HHI pair builder and drawn more often by the sampler."""
from __future__ import annotations

import numpy as np
import pytest

from model_runtime.data.library import ClipLibrary, derived_kind
from model_runtime.data.new_clips import partner_clip_name
from model_runtime.data.pairs import build_hhi_pairs
from model_runtime.data.pairs.clips import ClipCache
from model_runtime.data.two_person import load_pairs
from model_runtime.data.two_person_pairs import add_two_person_pairs, main as pairs_main
from model_runtime.errors import RemogenError
from model_runtime.training.recipe import TWO_PERSON_WEIGHT
from model_runtime.training.samples import CLIP_KIND_WEIGHT
from synthetic import humanoid_bvh, scaled_copy, synthetic_library


@pytest.fixture
def take_folder(tmp_path):
    """One take: A walks, B walks beside it 0.8 m away (file units are cm), with a pairs.csv naming B's prompt."""
    folder = tmp_path / "takes"
    folder.mkdir()
    a, _ = humanoid_bvh(folder / "18_02.bvh", fps=120, seconds=2.0, unit=0.01)
    scaled_copy(a, folder / "19_02.bvh", scale=1.1, shift_x=80.0)
    (folder / "pairs.csv").write_text("a,b,caption,text\n18_02.bvh,19_02.bvh,walk together,a person walks beside "
                                      "someone\n")
    return folder


def test_each_person_becomes_an_ego_with_the_other_as_partner(take_folder):
    lib = synthetic_library()
    take = load_pairs(take_folder)[0]
    out, egos = add_two_person_pairs(lib, [take])
    assert out.names[:len(lib)] == lib.names                          # the library's clips keep their indices
    assert [out.names[i] for i in egos] == ["cmu/19_02#twoperson0", "cmu/18_02#twoperson0"]
    for i, (ego, partner) in zip(egos, ((take.b, take.a), (take.a, take.b))):
        k = out.names.index(partner_clip_name(out.names[i]))
        assert derived_kind(out.names[i]) == "twoperson" and k not in egos
        assert out.captions[i] == "a person walks beside someone" and out.sources[i] == "cmu"
        assert out.frames(i) == out.frames(k) == take.frames
        clips = ClipCache(out, [i, k])
        # the take's shared world is kept: FK of the stored clips gives both people where they were captured
        assert np.allclose(clips.joints(i), ego.joints, atol=2e-3)
        assert np.allclose(clips.joints(k), partner.joints, atol=2e-3)


def test_the_pair_builder_reads_them_as_two_person_pairs_without_a_clearance_rule(take_folder):
    lib = synthetic_library()
    take = load_pairs(take_folder)[0]
    out, egos = add_two_person_pairs(lib, [take])
    pairs = build_hhi_pairs(out, egos, seed=0)
    assert sorted(p.ego for p in pairs) == sorted(egos) and {p.kind for p in pairs} == {"two_person"}
    by_ego = {p.ego: p for p in pairs}
    assert np.allclose(by_ego[egos[0]].partner, take.a.joints, atol=2e-3)   # B's partner is A, as captured
    assert np.allclose(by_ego[egos[1]].partner, take.b.joints, atol=2e-3)
    assert TWO_PERSON_WEIGHT > 1.0 and CLIP_KIND_WEIGHT["twoperson"] == TWO_PERSON_WEIGHT


def test_touching_people_stay_a_pair(tmp_path):
    """Real people touch (a handshake): the derived kinds' clearance rules do not apply to a captured pair."""
    folder = tmp_path / "close"
    folder.mkdir()
    a, _ = humanoid_bvh(folder / "20_11.bvh", fps=120, seconds=2.0, unit=0.01)
    scaled_copy(a, folder / "21_11.bvh", shift_x=10.0)                 # 0.1 m apart: arms overlap
    out, egos = add_two_person_pairs(synthetic_library(), load_pairs(folder))
    assert len(build_hhi_pairs(out, egos, seed=0)) == 2


def test_a_take_is_appended_once(take_folder):
    takes = load_pairs(take_folder)
    lib = synthetic_library()
    out, _ = add_two_person_pairs(lib, takes)
    with pytest.raises(RemogenError, match="already holds .*cmu/19_02#twoperson0.*append each take once"):
        add_two_person_pairs(out, takes)
    # two takes whose files share a name would share clip names, and a partner is found by its clip's name
    with pytest.raises(RemogenError, match="name their clips alike .*its own name"):
        add_two_person_pairs(lib, takes + takes)


def test_command_line_appends_and_bad_input_changes_nothing(take_folder, tmp_path, capsys):
    lib_path = synthetic_library().save(tmp_path / "lib.npz")
    out_path = tmp_path / "lib_pairs.npz"
    assert pairs_main(["--library", str(lib_path), "--pairs", str(take_folder), "--out", str(out_path)]) == 0
    assert "1 take(s) as 2 HHI egos" in capsys.readouterr().err
    assert len(ClipLibrary.load(out_path)) == len(ClipLibrary.load(lib_path)) + 4
    missing = tmp_path / "nowhere"
    assert pairs_main(["--library", str(lib_path), "--pairs", str(missing), "--out", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "not found" in err and "\n" not in err
    assert not (tmp_path / "x.npz").exists()

"""Captions from dataset labels (Bandai Namco, HDM05, CMU descriptions) and the Bandai Namco repository layout."""
import pytest

from model_runtime.data.captions import bandai_caption, caption_for, cmu_caption, hdm05_caption
from paths import DATA, data_file



def test_caption_phrases():
    assert bandai_caption("walk-left", "tired") == "a person walks to the left, tired"
    assert bandai_caption("bow", "happy") == "a person bows, happily"
    assert bandai_caption("walk", "normal") == "a person walks forward"
    assert hdm05_caption("walkRightCircle4StepsRstart") == "a person walks in a circle to the right"
    assert hdm05_caption("kickLFront1Reps") == "a person kicks forward with the left leg"
    assert hdm05_caption("sitDownChair") == "a person sits down on a chair"
    assert cmu_caption('"slow walk"') == "a person walks slowly"
    assert cmu_caption("playground - climb, sit") == "a person plays on a playground: climbs and sits"
    assert cmu_caption("bend over, scoop up, rise, lift arm") == "a person bends over, scoops up, rises and lifts arm"
    assert caption_for("HDM_bd_jumpingJack1Reps_001_120.amc") == "a person does jumping jacks"
    assert caption_for("somewhere/else.bvh") is None


def test_every_bandai_label_has_a_phrase():
    from model_runtime.data.captions import BANDAI_CONTENT, BANDAI_STYLE, _labels
    cfgs = sorted(DATA.glob("bandai/dataset-*/cfg"))
    if not cfgs:
        pytest.skip("Bandai Namco test data not present beside the repository")
    for cfg in cfgs:
        assert set(_labels(cfg / "content_label.txt")) <= set(BANDAI_CONTENT)
        assert set(_labels(cfg / "style_label.txt")) <= set(BANDAI_STYLE)


@pytest.mark.parametrize("rel, caption", [
    ("bandai/dataset-1/data/dataset-1_walk-left_tired_001.bvh", "a person walks to the left, tired"),
    ("bandai/dataset-1/data/dataset-1_bow_happy_001.bvh", "a person bows, happily"),
    ("bandai/dataset-1/data/dataset-1_dash_giant_001.bvh", "a person dashes forward, like a giant"),
    ("bandai/dataset-2/data/dataset-2_wave-left-hand_elderly_001.bvh",
     "a person waves the left hand, like an elderly person"),
])
def test_bandai_captions_from_json_ids(rel, caption):
    assert caption_for(data_file(rel)) == caption


def test_cmu_captions_from_the_index():
    index = data_file("cmu/index.csv")
    assert caption_for(data_file("cmu/daz_friendly_120fps/07/07_01.bvh"), index) == "a person walks"
    assert caption_for(data_file("cmu/cc_retarget_60fps/002/002_05.bvh"), index) == "a person punches"
    assert caption_for(data_file("cmu/daz_friendly_120fps/07/07_01.bvh")) is None


# ------------------------------------------------------------------------------ Bandai repository checkout

def test_bandai_repository_adds_only_takes_the_data_folder_lacks(tmp_path):
    """--bandai-repo reads the repository layout, takes content/style from the file name and skips clips
    the data folder already has, so a larger run never counts a clip twice."""
    from model_runtime.data.clip_files import bandai_repository_files
    src = data_file("bandai/dataset-2/data/dataset-2_walk-turn-left_normal_001.bvh")
    data = tmp_path / "repo" / "dataset" / "Bandai-Namco-Research-Motiondataset-2" / "data"
    data.mkdir(parents=True)
    (data / src.name).write_bytes(src.read_bytes())                                   # already in the data folder
    (data / "dataset-2_walk-turn-left_normal_042.bvh").write_bytes(src.read_bytes())  # a take it lacks
    (data / "README.bvh").write_text("not a take")                                     # not a take name
    files = bandai_repository_files(tmp_path / "repo", skip={src.stem})
    assert [(f.path.name, f.name, f.source, f.caption) for f in files] == [
        ("dataset-2_walk-turn-left_normal_042.bvh", "bandai/dataset-2_walk-turn-left_normal_042", "bandai",
         "a person walks and turns left")]


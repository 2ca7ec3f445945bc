"""Colour words the named-colour table lacks, read as the table name nearest in the text embedding.

The table (``core.named_colours``: the XKCD survey's and CSS4's names) holds about a thousand
names, but a prompt may spell one otherwise ("vermilion" for the survey's "vermillion") or use a
word it lacks. The add-on's reading (``core.prompt``, no torch) keeps such a word aside
(``Reading.unread_colour``: a word no vocabulary knows, just before the material's word); here
the generator's own text encoder (MiniLM, ``text.py``) embeds it and takes the table name of the
highest cosine, if it is at least ``THRESHOLD``: spellings and near-synonyms pass (0.85 for
"vermilion"), words that are no colour do not ("new" 0.42, "kettle" 0.62 to their nearest names).
The names' embeddings take 23 s on one thread: they are kept in ``data/`` with the table's digest
(``python -m torch_models.generator.colour_words`` remakes them); a changed table is noticed and
they are made in memory instead.
"""
from __future__ import annotations

import hashlib
from dataclasses import replace
from functools import cache
from pathlib import Path

import numpy as np
import torch

from richmat_addon.core import named_colours
from richmat_addon.core.prompt import Reading
from . import text

THRESHOLD = 0.75
EMBEDDINGS = Path(__file__).resolve().parent / "data" / "colour_name_embeddings.npz"


def table_digest() -> str:
    return hashlib.sha256(named_colours.TABLE.read_bytes()).hexdigest()


def write_embeddings(path: Path = EMBEDDINGS) -> None:
    """Embed every table name and keep them (float16) with the table's digest."""
    names = list(named_colours.table())
    with torch.no_grad():
        vectors = text.embed(names).numpy().astype(np.float16)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, names=np.array(names), vectors=vectors, table_sha256=np.array(table_digest()))


@cache
def _embedded() -> tuple[list[str], torch.Tensor]:
    """The names and their embeddings: the kept ones, or made now (and not kept) when the table changed."""
    if EMBEDDINGS.is_file() and str(np.load(EMBEDDINGS)["table_sha256"]) == table_digest():
        data = np.load(EMBEDDINGS)
        return [str(n) for n in data["names"]], torch.from_numpy(data["vectors"].astype(np.float32))
    names = list(named_colours.table())
    with torch.no_grad():
        return names, text.embed(names)


def nearest_name(word: str) -> tuple[str, float]:
    """The table name whose embedding is nearest ``word``'s, and their cosine."""
    names, vectors = _embedded()
    with torch.no_grad():
        scores = vectors @ text.embed([word])[0]
    best = int(scores.argmax())
    return names[best], float(scores[best])


def with_colour_word(reading: Reading) -> Reading:
    """``reading`` with its unread colour word read as its nearest table name, where near enough."""
    if reading.colour is not None or reading.unread_colour is None:
        return reading
    name, score = nearest_name(reading.unread_colour)
    if score < THRESHOLD:
        return reading
    colour = tuple(float(c) for c in named_colours.table()[name])
    return replace(reading, colour_name=f"{name} (for {reading.unread_colour!r}, cosine {score:.2f})", colour=colour)


if __name__ == "__main__":
    torch.set_num_threads(1)
    write_embeddings()
    print(f"wrote {EMBEDDINGS}")

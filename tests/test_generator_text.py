"""The offline MiniLM sentence embedding used as the generator's text condition."""
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
import torch

from torch_models.generator import text


@contextmanager
def text_encoder() -> Iterator[None]:
    """Skip where the MiniLM wheel is missing: an external package the Makefile installs, not shipped
    here. Anything else that fails, a missing shipped file included, fails the test."""
    try:
        yield
    except text.TextEncoderMissing as exc:
        pytest.skip(f"the external text-encoder wheel is not installed on this machine: {exc}")


def _embed(sentences):
    with text_encoder():
        return text.embed(sentences)


def test_unit_norm_and_deterministic():
    a = _embed(["a dusty grey ceramic vase", "a blue car paint with a glossy clearcoat"])
    b = _embed(["a dusty grey ceramic vase", "a blue car paint with a glossy clearcoat"])
    assert a.shape == (2, text.EMBEDDING_DIM)
    assert torch.allclose(a.norm(dim=1), torch.ones(2), atol=1e-5)
    assert torch.equal(a, b)


def test_similar_captions_are_closer_than_unrelated():
    e = _embed(["a red ceramic vase with a thick glossy coat", "a red ceramic pot with a glossy clearcoat",
                "rusty iron chair covered in heavy dust"])
    sim = e @ e.T
    assert sim[0, 1] > 0.6
    assert sim[0, 1] > sim[0, 2] + 0.3
    assert sim[1, 0] > sim[1, 2] + 0.3


def test_padding_does_not_change_the_embedding():
    """Pooling over real tokens only: the embedding of a sentence is independent of others."""
    alone = _embed(["light dust"])
    together = _embed(["light dust", "a much longer sentence about a wooden table with fuzz and scratches"])
    assert torch.allclose(alone[0], together[0], atol=1e-6)
    tokens = text.encoder().tokenizer.encode("light dust").ids
    assert len(tokens) == 4  # [CLS] light dust [SEP], no padding to 128

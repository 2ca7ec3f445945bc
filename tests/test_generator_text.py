"""The offline MiniLM sentence embedding used as the generator's text condition."""
import pytest
import torch

text = pytest.importorskip("torch_models.generator.text")


def _embed(sentences):
    try:
        return text.embed(sentences)
    except text.TextEncoderMissing as exc:
        pytest.skip(str(exc))


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

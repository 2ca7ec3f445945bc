"""Colour words the named-colour table lacks, read by the generator's text embedding."""
import numpy as np
import torch

from richmat_addon.core import named_colours
from richmat_addon.core.prompt import read_prompt
from torch_models.generator import colour_words, text
from tests.test_generator_text import text_encoder

torch.set_num_threads(1)


def test_the_kept_embeddings_are_the_tables_names_embedded_now():
    data = np.load(colour_words.EMBEDDINGS)
    assert str(data["table_sha256"]) == colour_words.table_digest()  # made from the table that ships
    names = [str(n) for n in data["names"]]
    assert names == list(named_colours.table())
    with text_encoder():
        fresh = text.embed(names[:: len(names) // 8]).numpy()
    assert np.abs(data["vectors"][:: len(names) // 8].astype(np.float32) - fresh).max() < 2e-3  # float16


def test_an_unknown_word_before_the_material_is_read_as_its_nearest_colour_name_when_near():
    reading = read_prompt("vermilion paint with light dust")  # the survey spells it "vermillion"
    assert reading.colour is None and reading.unread_colour == "vermilion"
    assert any("'vermilion' is not a colour name" in line for line in reading.lines())
    with text_encoder():
        read = colour_words.with_colour_word(reading)
        assert read.colour_name.startswith("vermillion (for 'vermilion'")
        assert np.allclose(read.colour, named_colours.table()["vermillion"])
        far = colour_words.with_colour_word(read_prompt("kettle paint"))  # no colour: its nearest name is "tea"
    assert far.unread_colour == "kettle" and far.colour is None
    assert read_prompt("old paint").unread_colour is None and read_prompt("red paint").unread_colour is None

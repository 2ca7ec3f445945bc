"""The fit error readout: the panel's number and word per fitted material, the per-texel map beside
the latents, and the heat-map toggle on the object (a real fit in the pip bpy module)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from richmat_addon.core import neural_folder
from richmat_addon.core.fit_error import GRADES
from richmat_addon.core.folder_io import read_exr

from .test_addon_extension import extension_zip, script  # noqa: F401  (session fixture)

READOUT = r'''
obj = procedural_asset(TMP, size=16)
scene.richmat.enhancement_type = "2"
scene.richmat.output_dir = TMP + "/baked"
assert run_op("uplift_material")[0] == {"FINISHED"}
assert run_op("bake_parameters")[0] == {"FINISHED"}
panels = sys.modules[MODULE + ".blender.panels"]

class Layout:
    """Records what a panel draws."""
    def __init__(self, lines): self.lines = lines
    def column(self, **kw): return self
    def box(self): return self
    def separator(self): pass
    def label(self, text="", icon="NONE"): self.lines.append(("label", text, icon))
    def prop(self, *a, **kw): pass
    def operator(self, idname, text="", icon="NONE"): self.lines.append(("operator", idname, text))

def drawn():
    lines = []
    panels.draw_richmat(Layout(lines), bpy.context)
    return lines

out = {"before_fit": drawn()}
means = {}
for steps in STEPS:
    scene.richmat.fit_steps = steps
    res, err = run_op("fit_neural")
    assert res == {"FINISHED"}, err
    enhanced = obj.active_material
    record = json.loads((Path(enhanced.richmat.neural_dir) / "neural.json").read_text())
    means[steps] = record["fit_error"]["mean"]
    out[f"drawn_{steps}"] = drawn()
out["means"] = means
out["neural_dir"] = enhanced.richmat.neural_dir
res, err = run_op("show_fit_error")
shown = obj.active_material
out["show"] = [list(res), err, shown.name, shown.richmat.shown_over.name,
               bpy.path.abspath(shown.node_tree.nodes["tex_fit_error"].image.filepath)]
out["drawn_shown"] = drawn()
shown_name = shown.name
res, err = run_op("show_fit_error")
out["hide"] = [list(res), err, obj.active_material.name, shown_name in bpy.data.materials]
print("RESULT " + json.dumps(out))
'''


def test_the_panel_shows_the_fit_error_and_the_map_toggles(blender_run, extension_zip: Path,  # noqa: F811
                                                          tmp_path: Path):
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\nSTEPS = (1, 100)\n" + READOUT, extension_zip),
                         timeout=600.0)
    assert not [line for line in result["before_fit"] if "fit error" in str(line).lower()]
    means = {int(k): v for k, v in result["means"].items()}
    assert means[100] < means[1]  # a longer fit renders closer to the material it encodes
    for steps, mean in means.items():
        labels = [text for kind, text, _ in result[f"drawn_{steps}"] if kind == "label" and "fit error" in text]
        assert len(labels) == 1, result[f"drawn_{steps}"]
        number, word = labels[0].rsplit(" ", 2)[-2:]
        assert abs(float(number.rstrip(",")) - mean) < 5e-4 and word in GRADES
        assert ("operator", "richmat.show_fit_error", "Show Fit Error Map") in \
            [tuple(line) for line in result[f"drawn_{steps}"]]
    neural = neural_folder.read(Path(result["neural_dir"]))
    error = neural.fit_error
    assert error is not None and error.map is not None and error.mean == means[100]
    texels = read_exr(error.map)
    assert texels.shape == (*read_exr(neural.latent_paths[0]).shape[:2], 1) == (16, 16, 1)
    assert np.isfinite(texels).all() and (texels >= 0).all()
    assert abs(float(texels.mean()) - error.mean) < 2e-3 * max(1.0, error.mean)  # half floats
    res, err, shown, over, image = result["show"]
    assert res == ["FINISHED"], err
    assert shown.endswith(" (richmat fit error)") and over.endswith(" (richmat)")
    assert Path(image).resolve() == error.map.resolve()
    assert ("operator", "richmat.show_fit_error", "Hide Fit Error Map") in [tuple(x) for x in result["drawn_shown"]]
    res, err, back, left = result["hide"]
    assert res == ["FINISHED"] and back == over and not left

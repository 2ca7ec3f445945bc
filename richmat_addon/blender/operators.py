"""The add-on's operators. Each ``poll`` says why it cannot run (greyed-out button + tooltip).

Bad input is reported with ``{'ERROR'}`` and one sentence that names the fix;
every check runs before the first change, so a refused operator leaves the file
as it was.
"""
from __future__ import annotations

from pathlib import Path

import bpy

from . import bake, neural_assets, neural_backend, uplift
from .cycles_builder import enable_osl
from .pbr_source import InputProblem


def _settings(context: bpy.types.Context):
    return context.scene.richmat


def _mesh_with_material(cls, context: bpy.types.Context) -> bool:
    obj = context.active_object
    if obj is None or obj.type != "MESH":
        cls.poll_message_set("Select a mesh object")
        return False
    if obj.active_material is None:
        cls.poll_message_set(f"{obj.name} has no material")
        return False
    return True


def _enhanced(context: bpy.types.Context) -> bpy.types.Material | None:
    material = context.active_object.active_material
    return material if uplift.is_enhanced(material) else material.richmat.enhanced


def _needs_enhanced(cls, context: bpy.types.Context) -> bool:
    if not _mesh_with_material(cls, context):
        return False
    if _enhanced(context) is None:
        cls.poll_message_set("Run Uplift Material first")
        return False
    return True


class RICHMAT_OT_uplift_material(bpy.types.Operator):
    """Make an enhanced copy of the Principled BSDF material(s) and use it (the original is kept)"""

    bl_idname = "richmat.uplift_material"
    bl_label = "Uplift Material"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _mesh_with_material(cls, context)

    def execute(self, context: bpy.types.Context) -> set[str]:
        s = _settings(context)
        try:
            lines = uplift.uplift(context.active_object, s.all_slots, s.enhancement_type, s.seed)
        except InputProblem as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        enable_osl(context.scene)
        self.report({"INFO"}, "Uplifted " + "; ".join(lines) + ". Render engine set to Cycles on the CPU "
                    "with Open Shading Language (the enhanced shader is OSL)")
        return {"FINISHED"}


class RICHMAT_OT_switch_material(bpy.types.Operator):
    """Switch the slots between the original and the enhanced material"""

    bl_idname = "richmat.switch_material"
    bl_label = "Switch Original / Enhanced"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _needs_enhanced(cls, context)

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = context.active_object
        switched = []
        for index in uplift.slot_indices(obj, _settings(context).all_slots):
            slot = obj.material_slots[index]
            target = slot.material.richmat.original if uplift.is_enhanced(slot.material) \
                else slot.material.richmat.enhanced
            if target is not None:
                slot.material = target
                switched.append(target.name)
        self.report({"INFO"}, "Now using " + ", ".join(switched))
        return {"FINISHED"}


class RICHMAT_OT_bake_parameters(bpy.types.Operator):
    """Write the parameter maps at the input textures' resolution as EXR (constants stay constants)"""

    bl_idname = "richmat.bake_parameters"
    bl_label = "Bake Parameters"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _needs_enhanced(cls, context)

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            root = bake.output_root(context.scene)
            lines = bake.bake(context.active_object, _settings(context).all_slots, root)
        except (InputProblem, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, "Baked " + "; ".join(lines))
        return {"FINISHED"}


class RICHMAT_OT_export_materialx(bpy.types.Operator):
    """Write a MaterialX document and its textures, side by side with relative paths"""

    bl_idname = "richmat.export_materialx"
    bl_label = "Export MaterialX"
    bl_options = {"REGISTER"}

    directory: bpy.props.StringProperty(subtype="DIR_PATH", options={"HIDDEN"})

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _needs_enhanced(cls, context)

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        from ..core.mtlx import validate_document
        import MaterialX as mx

        if not self.directory:
            self.report({"ERROR"}, "Choose a folder to export to")
            return {"CANCELLED"}
        root = Path(bpy.path.abspath(self.directory)).resolve()
        try:
            root.mkdir(parents=True, exist_ok=True)
            lines = bake.bake(context.active_object, _settings(context).all_slots, root, relink=False)
        except (InputProblem, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        problems = []
        for document in sorted(root.glob("*/material.mtlx")):
            doc = mx.createDocument()
            mx.readFromXmlFile(doc, str(document))
            problems += [f"{document}: {p}" for p in validate_document(doc)]
        if problems:
            self.report({"ERROR"}, "MaterialX validation failed: " + "; ".join(problems[:3]))
            return {"CANCELLED"}
        self.report({"INFO"}, "Exported (valid MaterialX) " + "; ".join(lines))
        return {"FINISHED"}


class RICHMAT_OT_fit_neural(bpy.types.Operator):
    """Compress the baked material to two latent textures with the torch backend (Esc cancels)"""

    bl_idname = "richmat.fit_neural"
    bl_label = "Fit Neural Material"
    bl_options = {"REGISTER"}

    _job: neural_backend.FitJob | None = None
    _timer = None

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        if not _needs_enhanced(cls, context):
            return False
        enhanced = _enhanced(context)
        if not enhanced.richmat.bake_dir or not (Path(enhanced.richmat.bake_dir) / "params.json").is_file():
            cls.poll_message_set("Bake Parameters first: the fit reads the baked maps")
            return False
        return True

    def _start(self, context: bpy.types.Context) -> bool:
        prefs = neural_assets.preferences(context)
        enhanced = _enhanced(context)
        baked = Path(enhanced.richmat.bake_dir)
        try:
            python = neural_backend.choose_python(bpy.path.abspath(prefs.python))
            source = neural_backend.backend_root(bpy.path.abspath(prefs.source_dir))
            weights = bpy.path.abspath(prefs.weights_dir) if prefs.weights_dir else ""
            self._job = neural_backend.FitJob(python, baked, baked / "neural", _settings(context).fit_steps,
                                              source, weights)
            self._job.start()
        except neural_backend.BackendProblem as exc:
            self.report({"ERROR"}, str(exc))
            return False
        return True

    def _finish(self, context: bpy.types.Context) -> set[str]:
        try:
            done = self._job.finish()
        except neural_backend.BackendProblem as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        enhanced = _enhanced(context)
        enhanced.richmat.neural_dir = done["out"]
        assigned = neural_assets.assign_latents(enhanced, Path(done["out"]))
        self.report({"INFO"}, f"Neural material fitted into {done['out']}; {assigned}")
        return {"FINISHED"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Blocking run (scripts, background mode): same protocol, no progress bar."""
        if not self._start(context):
            return {"CANCELLED"}
        return self._finish(context)

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if not self._start(context):
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, _settings(context).fit_steps)
        self._timer = wm.event_timer_add(0.2, window=context.window)
        wm.modal_handler_add(self)
        self.report({"INFO"}, "Fitting neural material (Esc cancels)")
        return {"RUNNING_MODAL"}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if event.type == "ESC":
            self._job.cancel()
            self._end(context)
            self.report({"WARNING"}, "Neural fit cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        for e in self._job.poll():
            if e["event"] == "progress":
                context.window_manager.progress_update(int(e["step"]))
                context.workspace.status_text_set(
                    f"Richmat fit: step {e['step']}/{e['total']}, loss {e['loss']:.4f} (Esc cancels)")
        if self._job.running:
            return {"PASS_THROUGH"}
        self._end(context)
        return self._finish(context)

    def _end(self, context: bpy.types.Context) -> None:
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)


class RICHMAT_OT_unwrap_uvs(bpy.types.Operator):
    """Give the active mesh a UV map (xatlas when installed, else Smart UV Project)"""

    bl_idname = "richmat.unwrap_uvs"
    bl_label = "Unwrap UVs"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = context.active_object
        if obj is None or obj.type != "MESH":
            cls.poll_message_set("Select a mesh object")
            return False
        if obj.data.library is not None:
            cls.poll_message_set("The mesh is linked from a library; make it local first")
            return False
        return True

    def execute(self, context: bpy.types.Context) -> set[str]:
        from .unwrap import unwrap

        method = unwrap(context.active_object)
        self.report({"INFO"}, f"UV map added to {context.active_object.name} ({method})")
        return {"FINISHED"}


CLASSES = (RICHMAT_OT_uplift_material, RICHMAT_OT_switch_material, RICHMAT_OT_bake_parameters,
           RICHMAT_OT_fit_neural, RICHMAT_OT_export_materialx, RICHMAT_OT_unwrap_uvs)

"""The add-on's operators. Each ``poll`` says why it cannot run (greyed-out button + tooltip).

Bad input is reported with ``{'ERROR'}`` and one sentence that names the fix;
every check runs before the first change, so a refused operator leaves the file
as it was.
"""
from __future__ import annotations

from pathlib import Path

import bpy

from ..core.enhancement_types import DIELECTRIC_ONLY
from ..core import material_folder, neural_encoder
from ..core.folder_io import FormatError
from ..core.prompt import read_prompt
from . import bake, cycles_builder, mesh_maps, neural_assets, neural_backend, uplift
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
        cycles = uplift.cycles_choice(context.scene)
        try:
            lines = uplift.uplift(context.active_object, s.all_slots, s.enhancement_type, s.seed, cycles,
                                  amount=s.amount)
        except InputProblem as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, "Uplifted " + "; ".join(lines) + ". " + _engines_note(context.scene, cycles))
        return {"FINISHED"}


def _engines_note(scene: bpy.types.Scene, cycles: cycles_builder.Graph) -> str:
    if cycles == "osl":
        return "Cycles renders the exact OSL shader, EEVEE and Cycles without OSL the native nodes"
    if cycles_builder.osl_device(scene):
        return "Cycles and EEVEE render the native nodes (Toggle Cycles Graph for Cycles' exact OSL shader)"
    return ("Cycles and EEVEE render the native nodes (for Cycles' exact OSL shader: "
            f"{cycles_builder.switch_device_line(scene)})")


class RICHMAT_OT_toggle_cycles_graph(bpy.types.Operator):
    """Switch what Cycles renders for the enhanced materials: the exact OSL shader (CPU, OptiX; turns the
    scene's Open Shading Language on) or the native node graph (every device); EEVEE renders the native graph"""

    bl_idname = "richmat.toggle_cycles_graph"
    bl_label = "Toggle Cycles Graph (OSL / Native)"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        if not _needs_enhanced(cls, context):
            return False
        if cycles_builder.cycles_graph(_enhanced(context)) is None:
            cls.poll_message_set("This material has one graph only: Uplift it again")
            return False
        return True

    def execute(self, context: bpy.types.Context) -> set[str]:
        target: cycles_builder.Graph = "native" if cycles_builder.cycles_graph(_enhanced(context)) == "osl" else "osl"
        turned_on = ""
        if target == "osl":
            if not cycles_builder.osl_device(context.scene):
                self.report({"ERROR"}, cycles_builder.switch_device_line(context.scene))
                return {"CANCELLED"}
            turned_on = cycles_builder.turn_on_osl(context.scene)
        obj = context.active_object
        switched = []
        for index in uplift.slot_indices(obj, _settings(context).all_slots):
            material = obj.material_slots[index].material
            enhanced = material if uplift.is_enhanced(material) else material.richmat.enhanced
            if enhanced is not None and cycles_builder.cycles_graph(enhanced) is not None:
                cycles_builder.use_in_cycles(enhanced, target)
                switched.append(enhanced.name)
        self.report({"INFO"}, (f"{turned_on}. " if turned_on else "") + "Cycles now renders the "
                    f"{'exact OSL shader' if target == 'osl' else 'native nodes'} of " + ", ".join(switched))
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
        self.report({"INFO"}, "Baked " + "; ".join(lines) + bake.unsaved_note(context.scene))
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


class _BackendOperator:
    """What the operators running the torch backend share: the job in a child process, progress
    in the status bar, Esc cancels, and the resulting latents assigned to the enhanced material."""

    _job: neural_backend.BackendJob | None = None
    _timer = None
    _did = ""  # "fitted", "generated": the report's verb

    def _make_job(self, context: bpy.types.Context) -> neural_backend.BackendJob:
        raise NotImplementedError

    def _total(self, context: bpy.types.Context) -> int:
        raise NotImplementedError

    def _status(self, event: dict) -> str:
        raise NotImplementedError

    def _start(self, context: bpy.types.Context) -> bool:
        try:
            self._job = self._make_job(context)
            self._job.start()
        except (neural_backend.BackendProblem, InputProblem, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return False
        return True

    def _finish(self, context: bpy.types.Context) -> set[str]:
        try:
            done = self._job.finish()
        except neural_backend.BackendProblem as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        assigned = _assign_latents(context, Path(done["out"]))
        warnings = "".join(f"; warning: {w}" for w in done.get("warnings", []))
        self.report({"WARNING"} if warnings else {"INFO"},
                    f"Neural material {self._did} into {done['out']}; {assigned}{warnings}")
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
        wm.progress_begin(0, self._total(context))
        self._timer = wm.event_timer_add(0.2, window=context.window)
        wm.modal_handler_add(self)
        self.report({"INFO"}, f"{self.bl_label} (Esc cancels)")
        return {"RUNNING_MODAL"}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if event.type == "ESC":
            self._job.cancel()
            self._end(context)
            self.report({"WARNING"}, f"{self.bl_label} cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        for e in self._job.poll():
            if e["event"] == "progress":
                context.window_manager.progress_update(int(e["step"]))
                context.workspace.status_text_set(self._status(e))
            elif e["event"] == "stage":
                context.workspace.status_text_set(f"{self.bl_label}: {e['text']} (Esc cancels)")
        if self._job.running:
            return {"PASS_THROUGH"}
        self._end(context)
        return self._finish(context)

    def _end(self, context: bpy.types.Context) -> None:
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)


def _assign_latents(context: bpy.types.Context, out: Path) -> str:
    """Record the neural folder in the enhanced material and load its latent textures there."""
    enhanced = _enhanced(context)
    enhanced.richmat.neural_dir = str(out)
    return neural_assets.assign_latents(enhanced, out)


class RICHMAT_OT_fit_neural(_BackendOperator, bpy.types.Operator):
    """Compress the baked material to two latent textures: the encoder's at once (numpy), then
    refined by the torch backend when there is one (Esc cancels the refinement)"""

    bl_idname = "richmat.fit_neural"
    bl_label = "Fit Neural Material"
    bl_options = {"REGISTER"}
    _did = "fitted"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        if not _needs_enhanced(cls, context):
            return False
        enhanced = _enhanced(context)
        if not enhanced.richmat.bake_dir or not (Path(enhanced.richmat.bake_dir) / material_folder.RECORD).is_file():
            cls.poll_message_set("Bake Parameters first: the fit reads the baked maps")
            return False
        return True

    def _encode(self, context: bpy.types.Context) -> set[str] | None:
        """Write and assign the encoder's latents (numpy, no torch); the operator's result when
        that is all it does (an error, or no backend to refine them), None when the fit follows."""
        baked = Path(_enhanced(context).richmat.bake_dir)
        try:
            record = neural_encoder.encode_material(baked, baked / "neural", neural_assets.decoder_folder(context))
        except (InputProblem, FormatError, ValueError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        assigned = _assign_latents(context, baked / "neural")
        try:
            neural_assets.backend(context)
        except neural_backend.BackendProblem as exc:
            self.report({"INFO"}, f"Neural material encoded into {baked / 'neural'} ({record['fitted_vectors']} "
                        f"vectors, encoder only: not refined, {exc}); {assigned}")
            return {"FINISHED"}
        return None

    def execute(self, context: bpy.types.Context) -> set[str]:
        return self._encode(context) or super().execute(context)

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        return self._encode(context) or super().invoke(context, event)

    def _make_job(self, context: bpy.types.Context) -> neural_backend.BackendJob:
        baked = Path(_enhanced(context).richmat.bake_dir)
        backend = neural_assets.backend(context)
        s = _settings(context)
        return neural_backend.FitJob(backend.python, baked, baked / "neural", s.fit_steps,
                                     str(neural_assets.decoder_folder(context)), s.fit_budget,
                                     source_root=backend.source_root)

    def _total(self, context: bpy.types.Context) -> int:
        return _settings(context).fit_steps

    def _status(self, event: dict) -> str:
        return f"Richmat fit: step {event['step']}/{event['total']}, loss {event['loss']:.4f} (Esc cancels)"


class RICHMAT_OT_generate_material(_BackendOperator, bpy.types.Operator):
    """Generate a neural material for the active mesh from the prompt (torch backend; Esc cancels).
    Uplifts the active material to the type, strengths and base material the prompt names and bakes it first"""

    bl_idname = "richmat.generate_material"
    bl_label = "Generate Material"
    bl_options = {"REGISTER"}
    _did = "generated"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        if not _mesh_with_material(cls, context):
            return False
        if not neural_assets.backend_in_sight(context):
            cls.poll_message_set(f"Generate needs the torch backend: {neural_backend.INSTALL_HINT}")
            return False
        if not mesh_maps.has_uvs(context.active_object):
            cls.poll_message_set("The latents live in the UV map: run Unwrap UVs first")
            return False
        if not _settings(context).prompt.strip():
            cls.poll_message_set("Type a prompt first (e.g. \"red paint with light dust\")")
            return False
        return True

    def _make_job(self, context: bpy.types.Context) -> neural_backend.BackendJob:
        s, obj = _settings(context), context.active_object
        backend = neural_assets.backend(context)  # before any change: a missing backend changes nothing
        type_ = read_prompt(s.prompt).type
        cycles = uplift.cycles_choice(context.scene)
        words = {"prompt": s.prompt, "base": s.base_colour.lower()}  # the prompt's base material and strengths
        try:
            uplift.uplift(obj, False, str(type_), s.seed, cycles, words=words)
        except InputProblem:
            if type_ not in DIELECTRIC_ONLY:
                raise
            uplift.uplift(obj, False, str(read_prompt(s.prompt, metallic=True).type), s.seed, cycles,
                          words=words)  # a metal
        bake.bake(obj, False, bake.output_root(context.scene))
        baked = Path(_enhanced(context).richmat.bake_dir)
        mesh = baked / "generate_mesh.obj"
        mesh_maps.write_obj(obj, [obj.active_material_index], mesh)
        prefs = neural_assets.preferences(context)
        checkpoint = bpy.path.abspath(prefs.generator_dir) if prefs.generator_dir else ""
        return neural_backend.GenerateJob(backend.python, mesh, baked, baked / "neural", s.prompt.strip(),
                                          s.generate_steps, s.seed, checkpoint, source_root=backend.source_root)

    def _total(self, context: bpy.types.Context) -> int:
        return _settings(context).generate_steps

    def _status(self, event: dict) -> str:
        return f"Richmat generate: sampling step {event['step']}/{event['total']} (Esc cancels)"


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

        try:
            result = unwrap(context.active_object)
        except InputProblem as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"WARNING"} if result.stretched else {"INFO"}, result.message(context.active_object.name))
        return {"FINISHED"}


CLASSES = (RICHMAT_OT_uplift_material, RICHMAT_OT_switch_material, RICHMAT_OT_toggle_cycles_graph,
           RICHMAT_OT_bake_parameters,
           RICHMAT_OT_fit_neural, RICHMAT_OT_generate_material, RICHMAT_OT_export_materialx, RICHMAT_OT_unwrap_uvs)

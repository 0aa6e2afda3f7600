"""The model card as others read it: its JSON Schema, and a compensator described in words.

``schemas/model_card.schema.json`` (JSON Schema 2020-12, in the package) writes down the card
(``metadata_props``, values JSON-decoded, as ``Compensator.metadata`` holds them; the keys'
authoritative text is ``compensator.py``'s). It is versioned with the contract: its ``$id`` ends
in the contract version it describes, ``postproc_contract`` is one of the versions this postproc
reads; ``load_model`` refuses a newer one naming it. ``card_problems`` checks a card against it
(the ``jsonschema`` package: ``postproc[report]``/``[test]``; ``postproc model info`` says when it
is not installed). ``interface_lines`` / ``card_lines``: what ``postproc model info`` prints;
``configuration_text``: that a model's ``joints`` input decides the arm configuration (``model
info``, ``compensate -v``).
"""
from __future__ import annotations

import json
from functools import cache

import numpy as np

from ..core.resources import schema_path
from .compensator import Compensator
from .contract import (
    INPUT_POSE,
    OUTPUT_ERROR,
    OUTPUT_JOINTS,
    OUTPUT_ROTATION,
    OUTPUT_STD,
    contract_version,
)

__all__ = ["SCHEMA_PATH", "schema", "card_problems", "interface_lines", "card_lines", "configuration_text",
           "load_lines"]

SCHEMA_PATH = schema_path("model_card.schema.json")

_OUTPUTS = {
    OUTPUT_ERROR: "E = P_target - P_actual, mm (robot base frame)",
    OUTPUT_JOINTS: "the nominal IK's joint angles of pose, deg, wrapped to [-180, 180)",
    "joints": "the nominal IK's joint angles of pose, deg (contract 1's name of ik_joints)",
    OUTPUT_ROTATION: "rotation vector nominal -> actual, deg (base frame)",
    OUTPUT_STD: "std of a coordinate of E - Ê at the target, mm",
}


@cache
def schema() -> dict:
    return json.loads(SCHEMA_PATH.read_text(encoding="utf-8"))


def card_problems(card: dict) -> list[str]:
    """What in ``card`` (a decoded model card) the schema does not allow: "key.path: message"
    per problem, [] when it is valid. Needs ``jsonschema``."""
    import jsonschema

    validator = jsonschema.Draft202012Validator(schema())
    return [f"{'.'.join(map(str, e.absolute_path)) or '(card)'}: {e.message}"
            for e in sorted(validator.iter_errors(card), key=lambda e: list(map(str, e.absolute_path)))]


def configuration_text(model: Compensator) -> str | None:
    """For a model that takes ``joints``: that this input decides the arm configuration the
    model evaluates, and what it takes without it (the branch it identified); None for others."""
    if not model.wants_joints:
        return None
    ident = model.metadata.get("identified")
    branch = ""
    if isinstance(ident, dict) and ident.get("ik_branch") is not None:
        signs = ", ".join(f"{float(b):+g}" for b in ident["ik_branch"])
        branch = f" ({ident.get('ik_family') or 'IK'} branch [{signs}])"
    return ("the input joints decides the arm configuration: the model solves each pose on the branch (shoulder, "
            "elbow, wrist) of the joint angles fed there; where joints is left out, or a row is NaN, on the branch it "
            f"identified from its training data{branch}, and a target the robot reaches in another configuration then "
            "gets the correction of the wrong one")


def interface_lines(model: Compensator) -> list[str]:
    """The graph's inputs and outputs in words: name, shape, required or optional (and what an
    omitted input means); for a model with ``joints``, that it decides the arm configuration."""
    from .contract import DEFAULT_MEANING, INPUT_WIDTH

    lines = ["inputs (float32):"]
    overridable = {node.name for node in model.session.get_overridable_initializers()}
    for node in (*model.session.get_inputs(), *model.session.get_overridable_initializers()):
        if node.name == INPUT_POSE:
            how = "required: X,Y,Z mm, A,B,C deg (KUKA R = Rz(A)·Ry(B)·Rx(C)), robot base frame"
        elif node.name in model.defaults:
            how = f"optional, omitted = {DEFAULT_MEANING.get(node.name, 'its default')}"
            if node.name in overridable:
                how += (" (a contract-2 file: onnxruntime lists it in get_overridable_initializers(), not "
                        "get_inputs(), and warns at each session; `postproc model upgrade` makes it an ONNX optional input)")
        else:
            how = "required by this graph (a contract-1 file: feed every input; `postproc model upgrade` makes it optional)"
        lines.append(f"  {node.name} [N, {INPUT_WIDTH.get(node.name, 6)}]: {how}")
    configuration = configuration_text(model)
    if configuration:
        lines.append(f"  {configuration}")
    lines.append("outputs (float32):")
    for node in model.session.get_outputs():
        width = node.shape[1] if len(node.shape) == 2 else "?"
        lines.append(f"  {node.name} [N, {width}]: {_OUTPUTS.get(node.name, '')}".rstrip(": "))
    return lines


def _load(row) -> str:
    mass, *com = (float(v) for v in row)
    return f"{mass:g} kg at ({', '.join(f'{c:g}' for c in com)}) mm"


def load_lines(model: Compensator) -> list[str]:
    """The loads the model was measured with and what it does with another one, in words."""
    loads, measured, ref = model.loads, model.measured_loads, model.reference_load
    if not loads and not model.takes_load:
        return []
    lines = []
    if len(measured):
        rows = loads.get("rows")
        counts = (f" ({', '.join(str(r) for r in rows)} rows)" if isinstance(rows, list) and len(rows) == len(measured)
                  else "")
        lines.append(f"loads measured: {'; '.join(_load(r) for r in measured)}{counts} "
                     "(mass, centre of mass in the flange frame)")
    else:
        lines.append("loads measured: not stated")
    if model.takes_load:
        k = float(loads.get("extrapolate", 1.0))
        nan = f"a NaN row = {_load(ref) if ref is not None else 'the reference load'}"
        if len(np.unique(measured[:, 0])) > 1:
            reach = f"reaches 0…{k * measured[:, 0].max():g} kg ({k:g} × the largest measured mass)"
        else:
            reach = ("measured at one mass: reaches that load only (measure at two or more loads for other "
                     "loads)") if len(measured) else "reaches no stated load"
        lines.append(f"load-aware: input load [N, 4] (the error at each target's payload); {nan}; {reach}")
    elif len(measured):
        lines.append("load-blind: no input load; the error at any other load than "
                     + ("the one" if len(measured) == 1 else "those") + " measured is not modelled")
    return lines


def _fmt(values, digits: int = 1) -> str:
    return ", ".join(f"{float(v):.{digits}f}" for v in values)


def card_lines(model: Compensator) -> list[str]:
    """The model card in words, one fact a line."""
    card = model.metadata
    lines = [f"name: {model.name}", f"file: {model.path} (sha256 {model.sha256})",
             f"contract: {contract_version(card)}"]
    for key in ("robot", "method", "structure"):
        if card.get(key):
            lines.append(f"{key}: {card[key]}")
    tool = model.tool
    if tool:
        frame = f" = {{{_fmt(tool['frame'], 3)}}} on the flange" if tool.get("frame") is not None else ""
        lines.append(f"tool: {tool.get('name', '')}{frame}" + (f"; valid for {tool['valid']}" if tool.get("valid") else ""))
    env = model.envelope
    if env is not None:
        b = env.box
        lines.append(f"envelope: X {b[0]:.1f}…{b[1]:.1f}, Y {b[2]:.1f}…{b[3]:.1f}, Z {b[4]:.1f}…{b[5]:.1f} mm; "
                     f"A,B,C {_fmt(env.attitude)} ± {env.range:g}° (per component)")
        if env.joints is not None:
            lines.append("trained joint arcs (deg): " + "; ".join(f"A{j + 1} {lo:.1f}…{hi:.1f}"
                                                                  for j, (lo, hi) in enumerate(env.joints)))
    reach = card.get("reach")
    if isinstance(reach, dict):
        lines.append(f"reach: {reach.get('radius_min', 0):g}…{reach['radius_max']:g} mm from ({_fmt(reach['center'])})")
    if card.get("controller_base") is not None:
        lines.append(f"controller base in the model's frame: {{{_fmt(card['controller_base'], 3)}}}")
    acc = card.get("accuracy")
    if isinstance(acc, dict) and acc.get("val_mean_mm") is not None:
        before = (f" (uncompensated {acc['val_uncompensated_mean_mm']:.3f} mm)"
                  if acc.get("val_uncompensated_mean_mm") is not None else "")
        lines.append(f"held-out |E - Ê|: mean {acc['val_mean_mm']:.3f} mm, max {acc.get('val_max_mm') or 0:.3f} mm "
                     f"over {acc.get('n_val', '?')} rows{before}; trained on {acc.get('n_train', '?')} rows")
    lines.extend(load_lines(model))
    lines.append(f"iterations: {model.default_iterations} (c = P + Ê(c) from c0 = P)")
    if model.max_std_mm is not None:
        lines.append(f"uncertainty: error_std bound {model.max_std_mm:g} mm (P336)")
    ident = card.get("identified")
    if isinstance(ident, dict) and isinstance(ident.get("parameters"), dict):
        groups = ident["parameters"]
        lines.append(f"identified: {sum(len(v) for v in groups.values())} parameters ({', '.join(groups)}); "
                     "`postproc export` writes them as URDF / YAML / JSON")
    update = card.get("update")
    if isinstance(update, dict):
        lines.append(f"re-calibrated from {update.get('from', '?')} on {update.get('rows', '?')} rows")
    campaigns = card.get("campaigns")
    if isinstance(campaigns, list) and len(campaigns) > 1:
        said = []
        for c in campaigns:
            f = c.get("frame") if isinstance(c, dict) else None
            if not isinstance(f, dict) or f.get("reference"):
                said.append(f"{c.get('name', '?')} ({c.get('rows', '?')} rows; the model's frame)")
                continue
            turn = float(np.linalg.norm(f.get("rotation_deg", [0, 0, 0])))
            shift = float(np.linalg.norm(f.get("offset_mm", [0, 0, 0])))
            said.append(f"{c.get('name', '?')} ({c.get('rows', '?')} rows; its frame {turn:.3g}° / {shift:.3g} mm "
                        "from the model's)")
        lines.append(f"campaigns: {len(campaigns)} in one fit, each its own frame, tool and zero offsets: "
                     + ", ".join(said))
    if card.get("data_sha256"):
        lines.append(f"data sha256: {card['data_sha256']}")
    return lines

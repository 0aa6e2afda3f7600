"""postproc model: what a compensator is (``info``) and an older one brought to this contract (``upgrade``)."""
from __future__ import annotations

import json
import sys

EXAMPLES = """examples:
  postproc model info models/default.onnx             inputs, outputs, the card in words
  postproc model info m.onnx --json                    the card (metadata, JSON-decoded) on stdout
  postproc model upgrade old.onnx -o new.onnx          a contract-1 or -2 file brought to contract 3

`info` checks the card against the model card's JSON Schema (postproc/schemas/model_card.schema.json;
needs the jsonschema package) and exits 1 if it does not hold; for a model with a joints input it says
that joints decides the arm configuration. `upgrade` keeps the graph's nodes and numbers; it makes
each optional input an ONNX optional input with its default (NaN rows; previous_pose: the pose
itself), so that onnxruntime runs the model with `pose` alone, lists every input in get_inputs()
and opens it without a warning.
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "model",
        parents=[common],
        formatter_class=formatter,
        help="a compensator's inputs, outputs and card (info); an older file brought to this contract (upgrade)",
        description="Describe an ONNX compensator as another program sees it, or upgrade an older one.",
        epilog=EXAMPLES,
    )
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    info = actions.add_parser("info", parents=[common], formatter_class=formatter,
                              help="inputs (required/optional), outputs and the model card in words")
    info.add_argument("model", metavar="MODEL.onnx")
    info.add_argument("--json", action="store_true", help="print the card as JSON on stdout instead")
    info.set_defaults(run=run_info)
    up = actions.add_parser("upgrade", parents=[common], formatter_class=formatter,
                            help="write MODEL.onnx with this contract's optional inputs (contract 3)")
    up.add_argument("model", metavar="MODEL.onnx")
    up.add_argument("-o", "--output", required=True, metavar="NEW.onnx")
    up.set_defaults(run=run_upgrade)


def run_info(args) -> int:
    from ..model.card import card_lines, card_problems, interface_lines
    from ..model.compensator import load_model

    model = load_model(args.model)
    try:
        problems = card_problems(model.metadata)
        checked = "the card holds to the model card schema"
    except ModuleNotFoundError:
        problems, checked = [], "card not checked against its schema (install jsonschema: pip install jsonschema)"
    if args.json:
        print(json.dumps(model.metadata, indent=2, ensure_ascii=False))
    else:
        print("\n".join([*card_lines(model), *interface_lines(model)]))
    for problem in problems:
        print(f"{model.path}: card does not hold to its schema: {problem}", file=sys.stderr)
    if not args.quiet and not problems:
        print(f"postproc model info: {checked}", file=sys.stderr)
    return 1 if problems else 0


def run_upgrade(args) -> int:
    from ..core import outputs
    from ..model.compensator import load_model
    from ..model.contract import upgrade

    target = outputs.check_outputs([args.output], [args.model])[0]
    old = load_model(args.model)
    new = upgrade(old.data)
    outputs.write([(target, new)])
    made = load_model(target)
    if not args.quiet:
        print(f"postproc model upgrade: {target}: optional inputs {', '.join(made.defaults) or '(none)'}",
              file=sys.stderr)
    return 0

"""The model: one ONNX file that maps commanded TCP poses to positioning errors, and what
runs it. The runtime (everything here but ``training``) needs numpy and onnxruntime only; it
never imports ``training``, which may import it.

Modules:

* ``compensator`` — THE CONTRACT's text (its module docstring), ``load_model``, ``Compensator``
  (predict, the fixed-point command c = P + Ê(c), chunked in execution order).
* ``contract`` — the contract's names, versions and metadata checks; the optional inputs'
  defaults every exported graph carries (``with_defaults``, ``upgrade``).
* ``envelope`` — the training envelope (box, attitude, joint arcs) and the one rule of where it
  ends (P301).
* ``settle`` — execution order (``Order``), what a program fed a part at a time carries
  (``Chain``), the approach settling of models that learn backlash (``Inside``: P321).
* ``session`` — onnxruntime sessions that start fast (each graph optimised once and kept).
* ``card`` — the model card: its JSON Schema and a model described in words (``model info``).
* ``identified`` — the identified parameters' names and units (torch-free).
* ``training/`` — fitting models (torch lives only there).
"""

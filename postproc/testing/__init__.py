"""What the tests and benchmarks share, importable from the installed package. The product itself
imports nothing from here.

| module | what it holds |
|---|---|
| ``models`` | small ONNX compensators built with onnx.helper (needs ``onnx``: ``postproc[test]``) |
| ``fuzz`` | the mutation fuzzer of ``compensate`` (``benchmarks/fuzz.py`` at full size) |
| ``generate`` | random programs of every dialect (hypothesis strategies) for the interpreter property |
| ``oracle`` | the interpreter property's check: input and compensated output run on concrete values |
| ``reflow`` | RAPID laid out again as controllers and editors write it (the layout property) |
"""

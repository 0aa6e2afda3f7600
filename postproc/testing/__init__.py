"""What the tests and benchmarks share, importable from the installed package: small ONNX
compensators built with onnx.helper (:mod:`.models`, needs ``onnx``: ``postproc[test]``) and the
mutation fuzzer of ``compensate`` (:mod:`.fuzz`). The product itself imports nothing from here."""

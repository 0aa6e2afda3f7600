"""ABB RAPID reader: module(s) (.mod, .modx, .prg, .sys) → Program, through the motion IR.

``syntax.py`` cuts the text into units and parses each distinct shape once
(``grammars/rapid.lark``); ``lower.py`` lowers the statements to the IR (``programs.ir``);
``semantics.py`` says what RAPID's constructs mean (work objects, tools, program
displacement, Offs/RelTool, external axes) for the one analysis (``programs.analysis``);
``syspar.py`` reads what the controller's system parameters (a backup's SYSPAR: MOC.cfg,
SYS.cfg) say of the task's robot (its base frame, a unit that moves it); ``reader.py`` puts
them together. tests/test_rapid.py and tests/test_rapid_ir.py show each
construct on a small module.
"""
from ..grammar import TOKEN_RE
from .lower import MOTION_OF, MOTIONS_OF
from .reader import RapidProgram, lower, read
from .syntax import parser

__all__ = ["read", "lower", "parser", "RapidProgram", "TOKEN_RE", "MOTION_OF", "MOTIONS_OF"]

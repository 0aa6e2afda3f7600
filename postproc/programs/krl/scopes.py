"""Declarations and name lookup: local (DEF), module (.src/.dat) and global ($config.dat) scopes."""
from __future__ import annotations

from lark import Token, Tree

from .values import _Agg, _Derived, _Unknown, _Var


class Scopes:
    """Declarations and name lookup: local (DEF), module (.src/.dat) and global ($config.dat) scopes. (methods of the Reader)"""

    def lookup(self, name: str):
        u = name.upper()
        for scope in (self.local, self.module, self.globals):
            if scope is not None and u in scope:
                return scope[u]
        return None

    def declare(self, name, type_, array, value=None, elems=None, glob=False):
        u = str(name).upper()
        if self.role == "effect" and value is None and self.local is not None and u in self.local:
            return self.local[u]  # DECL of a parameter bound at the call: keeps its value
        var = _Var(u, type_, array, value, {} if array else None)
        if self.role == "config" or (glob and self.local is None):  # $config.dat, DECL GLOBAL in a data list
            self.globals[u] = var
        elif self.local is not None:
            self.local[u] = var
        else:
            self.module[u] = var
        return var

    def s_decl(self, node):
        typ = None
        glob = any(isinstance(c, Token) and c.type == "GLOBAL" for c in node.children)
        for c in node.children:
            if isinstance(c, Tree) and c.data == "type":
                typ = c.children[0].upper()
            elif isinstance(c, Tree) and c.data == "decl_item":
                name = c.children[0]
                dims = next((x for x in c.children[1:] if isinstance(x, Tree) and x.data == "dims"), None)
                init = c.children[-1] if len(c.children) > 1 and c.children[-1] is not dims else None
                val = self.value(init) if init is not None else None
                if isinstance(val, _Agg) and val.type is None and typ:
                    val.type = typ
                self.declare(name, typ, dims is not None, None if dims is not None else val, glob=glob)

    def s_struc_decl(self, node):
        """``STRUC name type field, field, type field``: the member types (upper case)."""
        fields_ = [c for c in node.children if isinstance(c, Tree) and c.data == "struc_field"]
        name = next(c for c in node.children if isinstance(c, Token) and c.type == "NAME")
        members, typ = {}, ""
        for f in fields_:
            names = [c for c in f.children if isinstance(c, Token) and c.type == "NAME"]
            if len(names) == 2:
                typ = names[0].upper()
            members[names[-1].upper()] = typ
        self.strucs[str(name).upper()] = members

    def s_enum_decl(self, node):
        pass

    s_signal_decl = s_ext_decl = s_enum_decl

    def position_source(self, expr, own: str = ""):
        """The first position variable other than ``own`` (one with a Cartesian value, or
        derived itself) that the expression reads, as written; None when it reads none."""
        stack = [expr]
        while stack:
            node = stack.pop()
            if not hasattr(node, "data"):
                continue
            if node.data == "name":
                n = node.children[0]
                var = self.lookup(str(n))
                if var is not None and not var.array and var.name != own and (
                        (isinstance(var.value, _Agg) and var.value.kind() == "cart")
                        or isinstance(var.value, _Derived)):
                    return str(n)
                continue
            stack.extend(reversed([c for c in node.children if c is not None]))
        return None

    def fdat_of(self, expr):
        if expr.data == "name":
            var = self.lookup(expr.children[0])
            if var is not None and isinstance(var.value, _Agg):
                return var.value
        return _Unknown("FDAT_ACT is a run-time value", (self.ln, 1))

    def where(self, fi):
        """(path, text) of file index ``fi`` (negative: a $config.dat text)."""
        if fi >= 0:
            return self.files[fi], self.texts[fi]
        return ("$config.dat" if len(self.config) == 1 else f"$config.dat[{-1 - fi}]"), self.config[-1 - fi]

#!/usr/bin/env python3
"""gen_abi.py -- the ctypes layer of the rbcloth binding, generated from abi/rbcloth.h.

    gen_abi.py HEADER OUT_PY [OUT_C]    write the ctypes module (and the layout checker)
    gen_abi.py --check MODULE_PY CHECKER_OUTPUT
                                        compare the module's layouts with what the C
                                        compiler says (the checker's stdout); exit 1
                                        naming every difference

The module is never written by hand: the header's `typedef struct ... {} name;`
blocks become ctypes Structures, its enums and integer #defines constants, its
`RBC_*_SIZE_V*` macros sizes computed from the Structures, the function pointer
typedefs CFUNCTYPEs and rbc_api_v1's entries the function table. A field or an
entry appended to the header appears here at the next build, with no edit.
The C checker (OUT_C) includes the header and prints sizeof, alignment, the offset
and size of every field, and the value of every constant; --check fails on any
difference, so a layout that ctypes gets wrong (or a header construct this parser
misreads) stops the build instead of corrupting memory at run time.

The parser knows the header's dialect, no more: anything it does not understand
(a preprocessor condition, a declaration it cannot split, a type it cannot map) is
an error naming the line, never silently skipped. Standard library only.
"""
import re
import sys

BASE = {
    "uint8_t": "ctypes.c_uint8", "int8_t": "ctypes.c_int8",
    "uint16_t": "ctypes.c_uint16", "int16_t": "ctypes.c_int16",
    "uint32_t": "ctypes.c_uint32", "int32_t": "ctypes.c_int32",
    "uint64_t": "ctypes.c_uint64", "int64_t": "ctypes.c_int64",
    "float": "ctypes.c_float", "double": "ctypes.c_double",
    "size_t": "ctypes.c_size_t", "char": "ctypes.c_char", "int": "ctypes.c_int",
    "unsigned": "ctypes.c_uint", "void": None,
}


class ParseError(Exception):
    pass


def preprocess(text):
    """Strip comments and evaluate the header's #if blocks (nothing is defined but
    what the header defines: no _WIN32, no __cplusplus, no RBC_BUILDING_LIBRARY).
    Returns (code lines, #define pairs)."""
    text = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    # Continuation lines (a #define over several lines) are joined.
    text = text.replace("\\\n", " ")
    defined, defines, out, stack = set(), [], [], []
    for number, line in enumerate(text.split("\n"), 1):
        s = line.strip()
        active = all(stack)
        m = re.match(r"#\s*(\w+)\s*(.*)", s)
        if not m:
            out.append(line if active else "")
            continue
        directive, rest = m.group(1), m.group(2).strip()
        if directive in ("ifdef", "ifndef"):
            stack.append((rest in defined) == (directive == "ifdef"))
        elif directive == "if":
            c = re.fullmatch(r"(!?)\s*defined\s*\(\s*(\w+)\s*\)", rest)
            if not c:
                raise ParseError("line %d: #if %s: only #if [!]defined(NAME) is understood"
                                 % (number, rest))
            stack.append((c.group(2) in defined) != (c.group(1) == "!"))
        elif directive == "else":
            stack[-1] = not stack[-1]
        elif directive == "endif":
            stack.pop()
        elif directive == "define" and active:
            d = re.match(r"(\w+)(\s+(.*))?$", rest)
            defined.add(d.group(1))
            defines.append((d.group(1), (d.group(3) or "").strip(), number))
        elif directive == "include" or not active:
            pass
        else:
            raise ParseError("line %d: #%s is not understood" % (number, directive))
        out.append("")
    return out, defines


def statements(lines):
    """Top-level statements as (first line number, text): split at ';' outside
    braces; a `static inline` function body is dropped whole."""
    result, cur, depth, start = [], [], 0, None
    for number, line in enumerate(lines, 1):
        for ch in line + "\n":
            if start is None and not ch.isspace():
                start = number
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
                if depth == 0 and "".join(cur).lstrip().startswith("static"):
                    cur, start = [], None
                    continue
            if ch == ";" and depth == 0:
                result.append((start, " ".join("".join(cur).split())))
                cur, start = [], None
                continue
            cur.append(ch)
    if "".join(cur).strip():
        raise ParseError("unterminated statement at line %s" % start)
    return result


def split_top(s, sep=","):
    parts, depth, cur = [], 0, []
    for ch in s:
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        if ch == sep and depth == 0:
            parts.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    if "".join(cur).strip():
        parts.append("".join(cur).strip())
    return parts


def clean(decl):
    decl = re.sub(r"\b(RBC_CALL|RBC_API)\b", " ", decl)
    return " ".join(decl.split())


def parse_decl(decl, where):
    """One declaration -> dict(name, type: (base, pointer depth), array, fn)."""
    decl = clean(decl)
    m = re.fullmatch(r"(.*?)\(\s*\*\s*(\w+)\s*\)\s*\((.*)\)", decl)
    if m:
        ret = parse_type(m.group(1), where)
        params = [] if m.group(3).strip() in ("", "void") else [
            parse_decl(p, where) for p in split_top(m.group(3))]
        return {"name": m.group(2), "fn": (ret, params), "array": None, "type": None}
    m = re.fullmatch(r"(.*?)(\w+)\s*\[\s*(\w+)\s*\]", decl)
    if m:
        return {"name": m.group(2), "type": parse_type(m.group(1), where),
                "array": m.group(3), "fn": None}
    m = re.fullmatch(r"(.*?[\s*])(\w+)", decl)
    if not m:
        raise ParseError("%s: cannot read the declaration '%s'" % (where, decl))
    return {"name": m.group(2), "type": parse_type(m.group(1), where), "array": None, "fn": None}


def parse_type(t, where):
    depth = t.count("*")
    words = [w for w in t.replace("*", " ").split() if w not in ("const", "struct")]
    if len(words) != 1:
        raise ParseError("%s: cannot read the type '%s'" % (where, t))
    return (words[0], depth)


def parse_header(path):
    with open(path, encoding="utf-8") as f:
        lines, defines = preprocess(f.read())
    structs, funcptrs, aliases, constants, enums, sizes = [], {}, {}, {}, {}, {}
    last_alias = None
    for number, st in statements(lines):
        where = "%s:%d" % (path, number)
        m = re.fullmatch(r"typedef struct (\w+) \{(.*)\} (\w+)", st)
        if m:
            if m.group(1) != m.group(3):
                raise ParseError("%s: struct %s is typedef'd as %s" % (where, m.group(1), m.group(3)))
            fields = [parse_decl(f, where) for f in split_top(m.group(2), ";")]
            structs.append((m.group(1), fields))
            last_alias = None
            continue
        m = re.fullmatch(r"enum \{(.*)\}", st)
        if m:
            names = []
            for item in split_top(m.group(1)):
                e = re.fullmatch(r"(\w+)\s*=\s*(.+)", item)
                if not e:
                    raise ParseError("%s: enum item '%s' has no value" % (where, item))
                constants[e.group(1)] = evaluate(e.group(2), constants, where)
                names.append(e.group(1))
            if last_alias:
                enums[last_alias] = names
            last_alias = None
            continue
        if st.startswith("typedef "):
            d = parse_decl(st[len("typedef "):], where)
            if d["fn"]:
                funcptrs[d["name"]] = d["fn"]
            elif d["array"] is None:
                aliases[d["name"]] = d["type"]
                last_alias = d["name"]
            else:
                raise ParseError("%s: array typedefs are not understood" % where)
            continue
        if "(" in st:
            last_alias = None
            continue  # a function declaration: the binding calls the table's entries
        raise ParseError("%s: statement not understood: %s" % (where, st[:80]))
    for name, value, number in defines:
        where = "%s:%d" % (path, number)
        m = re.fullmatch(r"\(\s*\(uint32_t\)\s*offsetof\(\s*(\w+)\s*,\s*(\w+)\s*\)\s*\)", value)
        if m:
            sizes[name] = (m.group(1), m.group(2))
        elif value and re.fullmatch(r"[\w\s()<>|&+\-~x]+", value) and not re.search(
                r"__|\bdefined\b", value):
            try:
                constants[name] = evaluate(value, constants, where)
            except ParseError:
                if re.search(r"\d", value):
                    raise
    return structs, funcptrs, aliases, constants, enums, sizes


def evaluate(expr, known, where):
    e = re.sub(r"\b(0[xX][0-9a-fA-F]+|\d+)[uUlL]*\b", r"\1", expr)
    e = re.sub(r"\(\s*u?int\d+_t\s*\)", "", e)
    for name in re.findall(r"\b[A-Za-z_]\w*\b", e):
        if name not in known:
            raise ParseError("%s: '%s' names %s, not a known constant" % (where, expr, name))
    try:
        return int(eval(e, {"__builtins__": {}}, dict(known)))
    except Exception as exc:  # noqa: BLE001 (the message names the expression)
        raise ParseError("%s: cannot evaluate '%s': %s" % (where, expr, exc))


class Emitter:
    def __init__(self, structs, funcptrs, aliases):
        self.structs = {s for s, _ in structs}
        self.funcptrs = funcptrs
        self.aliases = aliases

    def resolve(self, base):
        seen = 0
        while base in self.aliases and seen < 16:
            b, depth = self.aliases[base]
            if depth:
                raise ParseError("pointer typedef %s is not understood" % base)
            base, seen = b, seen + 1
        return base

    def ctype(self, t, where):
        base, depth = t
        base = self.resolve(base)
        if base in self.structs:
            expr = base
        elif base in self.funcptrs:
            expr = base
        elif base in BASE:
            expr = BASE[base]
        else:
            raise ParseError("%s: no ctypes type for '%s'" % (where, base))
        if depth == 0:
            if expr is None:
                return "None"
            return expr
        if base == "char" and depth == 1:
            return "ctypes.c_char_p"
        if expr is None:
            expr, depth = "ctypes.c_void_p", depth - 1
        for _ in range(depth):
            expr = "ctypes.POINTER(%s)" % expr
        return expr

    def param(self, p, where):
        if p["fn"]:
            return self.fn(p["fn"], where)
        t = p["type"]
        if p["array"] is not None:  # `const float position[3]` is a pointer
            t = (t[0], t[1] + 1)
        return self.ctype(t, where)

    def fn(self, fn, where):
        ret, params = fn
        return "ctypes.CFUNCTYPE(%s%s)" % (
            self.ctype(ret, where), "".join(", " + self.param(p, where) for p in params))

    def field(self, f, where):
        if f["fn"]:
            return self.fn(f["fn"], where)
        t = self.ctype(f["type"], where)
        if f["array"] is not None:
            return "(%s * %s)" % (t, f["array"])
        return t


def write_module(header, out_py, out_c=None):
    structs, funcptrs, aliases, constants, enums, sizes = parse_header(header)
    em = Emitter(structs, funcptrs, aliases)
    o = ["# Generated by hosts/python/gen_abi.py from abi/rbcloth.h: do not edit.",
         "# ctypes layouts of every struct, the constants and the function table.",
         "import ctypes", "", "CONSTANTS = {"]
    o += ["    %r: %d," % kv for kv in constants.items()]
    o += ["}", "globals().update(CONSTANTS)", "", "# typedef name -> its enum's names",
          "ENUMS = {"]
    o += ["    %r: %r," % kv for kv in enums.items()]
    o += ["}", ""]
    for name, (base, depth) in aliases.items():
        if depth == 0 and em.resolve(name) in BASE and BASE[em.resolve(name)]:
            o.append("%s = %s" % (name, BASE[em.resolve(name)]))
    o.append("")
    for name, _ in structs:
        o.append("class %s(ctypes.Structure):\n    pass\n" % name)
    for name, fn in funcptrs.items():
        o.append("%s = %s" % (name, em.fn(fn, "typedef " + name)))
    o.append("")
    for name, fields in structs:
        o.append("%s._fields_ = [" % name)
        for f in fields:
            o.append("    (%r, %s)," % (f["name"], em.field(f, "%s.%s" % (name, f["name"]))))
        o.append("]")
    o += ["", "STRUCTS = %r" % [s for s, _ in structs], "",
          "# struct -> field -> the type it is declared with (enum typedefs are named)",
          "FIELD_TYPES = {"]
    for name, fields in structs:
        o.append("    %r: %r," % (name, {f["name"]: f["type"][0] for f in fields if f["type"]}))
    o += ["}", "",
          "# RBC_*_SIZE_* macros: (struct, field) whose offset is the size",
          "SIZE_MACROS = {"]
    o += ["    %r: %r," % kv for kv in sizes.items()]
    o += ["}",
          "for _n, (_s, _f) in SIZE_MACROS.items():",
          "    globals()[_n] = getattr(globals()[_s], _f).offset",
          ""]
    table = dict(structs).get("rbc_api_v1")
    if table is None:
        raise ParseError("%s: no rbc_api_v1 table" % header)
    o.append("# The function table's entries in order: name -> CFUNCTYPE (None: data).")
    o.append("API_ENTRIES = [")
    o += ["    %r," % f["name"] for f in table if f["fn"]]
    o += ["]", ""]
    with open(out_py, "w", encoding="utf-8") as f:
        f.write("\n".join(o) + "\n")
    if out_c:
        c = ["/* Generated by hosts/python/gen_abi.py: prints what the C compiler makes of",
             " * abi/rbcloth.h, for gen_abi.py --check to compare with the ctypes module. */",
             "#include <stdalign.h>", "#include <stdio.h>", '#include "rbcloth.h"', "",
             "int main(void) {"]
        for name, fields in structs:
            c.append('    printf("S %s %%zu %%zu\\n", sizeof(%s), alignof(%s));' % (name, name, name))
            for fl in fields:
                c.append('    printf("F %s %s %%zu %%zu\\n", offsetof(%s, %s), sizeof(((%s *)0)->%s));'
                         % (name, fl["name"], name, fl["name"], name, fl["name"]))
        for name in list(constants) + list(sizes):
            c.append('    printf("C %s %%lld\\n", (long long)(%s));' % (name, name))
        c += ["    return 0;", "}"]
        with open(out_c, "w", encoding="utf-8") as f:
            f.write("\n".join(c) + "\n")


def check(module_py, checker_output):
    import ctypes
    import importlib.util
    spec = importlib.util.spec_from_file_location("_rbc_abi_check", module_py)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    with open(checker_output, encoding="utf-8") as f:
        lines = [l.split() for l in f if l.strip()]
    bad, count, seen = [], 0, set()
    for kind, *rest in lines:
        count += 1
        if kind == "S":
            name, size, align = rest[0], int(rest[1]), int(rest[2])
            cls = getattr(mod, name, None)
            seen.add(name)
            if cls is None:
                bad.append("struct %s: missing from the module" % name)
            elif (ctypes.sizeof(cls), ctypes.alignment(cls)) != (size, align):
                bad.append("struct %s: C sizeof %d align %d, ctypes %d %d" % (
                    name, size, align, ctypes.sizeof(cls), ctypes.alignment(cls)))
        elif kind == "F":
            s, fname, off, size = rest[0], rest[1], int(rest[2]), int(rest[3])
            desc = getattr(getattr(mod, s, None), fname, None)
            if desc is None:
                bad.append("%s.%s: missing from the module" % (s, fname))
            elif (desc.offset, desc.size) != (off, size):
                bad.append("%s.%s: C offset %d size %d, ctypes %d %d" % (
                    s, fname, off, size, desc.offset, desc.size))
        elif kind == "C":
            name, value = rest[0], int(rest[1])
            if getattr(mod, name, None) != value:
                bad.append("%s: C %d, module %r" % (name, value, getattr(mod, name, None)))
    missing = set(mod.STRUCTS) - seen
    if missing:
        bad.append("structs the checker did not print: %s" % sorted(missing))
    for b in bad:
        print("gen_abi --check: " + b, file=sys.stderr)
    if count == 0:
        bad.append("empty checker output")
        print("gen_abi --check: the checker printed nothing", file=sys.stderr)
    return 1 if bad else 0


def main(argv):
    if len(argv) == 3 and argv[0] == "--check":
        return check(argv[1], argv[2])
    if len(argv) in (2, 3):
        try:
            write_module(*argv)
        except ParseError as e:
            print("gen_abi: %s" % e, file=sys.stderr)
            return 1
        return 0
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

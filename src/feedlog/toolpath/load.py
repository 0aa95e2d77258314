"""Part programs of any supported dialect: `load_program` = `dialects.translate` + `parse_program`.

    program = load_program("part.mpf")                      # Sinumerik, detected by suffix and words
    program = load_program(text, dialect="fanuc", lenient=True)

Every command that reads a part program goes through here, so a Fanuc/Hurco or Sinumerik program
reads the same everywhere; RS274/NGC (LinuxCNC) text is parsed exactly as before (the translation
leaves it alone). What the translation changed is at the head of `Program.warnings`, and
`Program.metadata["dialect"]` says which dialect was read.
"""

from __future__ import annotations

from pathlib import Path

from feedlog.errors import ProgramError
from feedlog.toolpath.dialects import DIALECTS, detect, translate
from feedlog.toolpath.interp import InterpOptions, interpret, needs_interpreter
from feedlog.toolpath.interp.sinumerik import sinumerik_program
from feedlog.toolpath.parser import parse_program
from feedlog.toolpath.program import Program
from feedlog.toolpath.source import read_source


def load_program(source: str | Path | Program, *, lenient: bool = False, dialect: str = "auto",
                 name: str | None = None, interp: InterpOptions | None = None) -> Program:
    """Parse a program (path, G-code text, or an already parsed Program, returned as is) of `dialect`
    (`auto`: detected from the file name and the text; see `toolpath.dialects`). Programs with
    parameters, expressions, O-words, canned cycles, polar coordinates or tool offsets go through the
    interpreter (toolpath.interp, LinuxCNC semantics; `interp` says where it finds subroutine files, the
    tool table and the parameter file); plain ones through the vectorised parser (the same table)."""
    if isinstance(source, Program):
        return source
    if dialect not in DIALECTS:
        raise ProgramError(f"unknown G-code dialect {dialect!r}; known: {', '.join(DIALECTS)}", file=name)
    text, path, label = read_source(source, name)
    front_end, front_end_refused = _fanuc_front_end(source, text, path, label, dialect, lenient, interp)
    if front_end is not None:
        return front_end
    translation = translate(text, dialect, name=path or label)
    if translation.dialect == "sinumerik":   # parameters, control flow, calls, cycles, frames: its own front-end
        program, refused = sinumerik_program(text, path, label, interp=interp, lenient=lenient)
        if program is not None:
            return program
        translation.notes[:0] = [refused] if refused else []
    native = translation.dialect == "rs274ngc" and dialect in ("auto", "rs274ngc")
    body = text if native else (translation.text if "\n" in translation.text else translation.text + "\n")
    program = None
    if needs_interpreter(body):
        try:
            program = interpret(source if native and path is not None else body, name=label, options=interp,
                                base_dir=path.parent if path is not None and not native else None)
            program.path = path
        except ProgramError as exc:
            if not lenient:
                raise
            refused = f"the interpreter refused it ({exc}); read leniently, skipping what it cannot read"
    if program is not None:
        pass
    elif native:
        try:
            program = parse_program(source if path is not None else text, lenient=lenient, name=label)
        except ProgramError as refused_by_parser:
            # what LinuxCNC reads that the vectorised parser does not (a full circle without end point,
            # two P words on a line): the interpreter, which follows LinuxCNC, decides
            try:
                program = interpret(source if path is not None else body, name=label, options=interp)
                program.path = path
            except ProgramError:   # both refuse: the parser's one-line error stays the answer
                raise refused_by_parser from None
    else:
        body = translation.text if "\n" in translation.text else translation.text + "\n"
        program = parse_program(body, lenient=lenient, name=label)
        program.path = path
    if program.metadata.get("interpreter") is None and needs_interpreter(body):
        program.warnings.insert(0, refused)
    if front_end_refused:
        program.warnings.insert(0, front_end_refused)
    program.metadata["dialect"] = translation.dialect
    if translation.notes:
        program.warnings[:0] = translation.notes
        program.metadata["dialect_changes"] = translation.notes
    return program


def _fanuc_front_end(source, text: str, path, label: str, dialect: str, lenient: bool,
                     interp: InterpOptions | None) -> tuple[Program | None, str | None]:
    """(program, None): a Fanuc / Hurco program with macro B, subprograms or canned cycles through the
    macro front-end (toolpath.interp.fanuc); (None, None) when the line translation reads it (plain
    programs, other dialects); with `lenient`, (None, why) for a program the front-end refuses: the
    translation then reads it, warned."""
    from feedlog.toolpath.interp.fanuc import interpret_fanuc, use_front_end
    detected = detect(text, path or label) if dialect == "auto" else dialect
    ngc = Path(str(path or label or "")).suffix.lower() == ".ngc"
    if not use_front_end(text, dialect, detected, ngc=ngc):
        return None, None
    try:
        program = interpret_fanuc(source if path is not None else text, name=label, options=interp)
    except ProgramError as exc:
        if not lenient:
            raise
        return None, f"the Fanuc macro front-end refused it ({exc}); read leniently by the line translation"
    program.path = path
    program.metadata["dialect"] = "hurco" if dialect == "hurco" else "fanuc"
    return program, None


STREAM_HEAD = 1 << 20   # bytes of a file that decide its dialect for a streamed read


def stream_dialect(path: str | Path, dialect: str = "auto") -> str:
    """The dialect a streamed read of `path` would meet: the given one, or the one its name and first
    MiB point at. Only RS274/NGC streams (`toolpath.stream` parses it without translation)."""
    if dialect not in DIALECTS:
        raise ProgramError(f"unknown G-code dialect {dialect!r}; known: {', '.join(DIALECTS)}", file=str(path))
    if dialect != "auto":
        return "fanuc" if dialect == "hurco" else dialect
    try:
        with open(path, "rb") as fh:
            head = fh.read(STREAM_HEAD).decode("utf-8", errors="replace")
    except OSError:
        return "rs274ngc"     # the reader says what is wrong with the path
    detected = detect(head, path)
    from feedlog.toolpath.interp.fanuc import looks_macro_b
    ngc = Path(str(path)).suffix.lower() == ".ngc"
    return "fanuc" if detected == "rs274ngc" and looks_macro_b(head, ngc=ngc) else detected

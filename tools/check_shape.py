#!/usr/bin/env python3
"""
Check the shape the codebase keeps (run from anywhere; exit status 1 on a breach):

- no function longer than 60 lines of code (its docstring excluded);
- no module of the package longer than 450 lines;
- no import of a private numpy or scipy module, and no ``exec``;
- README.md at most 20 kB, and no file in doc/ over 30 kB.
"""

from __future__ import annotations

import ast
from pathlib import Path
import re
import sys

ROOT = Path(__file__).resolve().parent.parent
MAX_FUNCTION_LINES = 60
MAX_MODULE_LINES = 450
MAX_README_BYTES = 20_000
MAX_DOC_BYTES = 30_000
PRIVATE_IMPORT = re.compile(r'^\s*(from|import)\s+(numpy|scipy)(\.\w+)*\._', re.M)


def function_lines(node: ast.AST) -> int:
    """Lines of a function's body, its docstring left out."""
    body = node.body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]
    return body[-1].end_lineno - body[0].lineno + 1 if body else 0


def breaches(root: Path = ROOT) -> list[str]:
    """Every breach of the limits above, one line each."""
    out = []
    for path in sorted((root / 'extended_tracker').rglob('*.py')):
        src = path.read_text()
        rel = path.relative_to(root)
        n_lines = len(src.splitlines())
        if n_lines > MAX_MODULE_LINES:
            out.append(f'{rel}: {n_lines} lines (at most {MAX_MODULE_LINES})')
        if PRIVATE_IMPORT.search(src):
            out.append(f'{rel}: imports a private numpy or scipy module')
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                k = function_lines(node)
                if k > MAX_FUNCTION_LINES:
                    out.append(f'{rel}:{node.lineno} {node.name}: {k} lines '
                               f'(at most {MAX_FUNCTION_LINES})')
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                  and node.func.id == 'exec'):
                out.append(f'{rel}:{node.lineno}: calls exec')
    readme = root / 'README.md'
    if readme.exists() and readme.stat().st_size > MAX_README_BYTES:
        out.append(f'README.md: {readme.stat().st_size} bytes (at most {MAX_README_BYTES})')
    for doc in sorted((root / 'doc').glob('*')) if (root / 'doc').is_dir() else []:
        if doc.is_file() and doc.stat().st_size > MAX_DOC_BYTES:
            out.append(f'{doc.relative_to(root)}: {doc.stat().st_size} bytes '
                       f'(at most {MAX_DOC_BYTES})')
    return out


def main() -> int:
    found = breaches()
    for line in found:
        print(line)
    print(f'{len(found)} breaches' if found else 'shape ok')
    return 1 if found else 0


if __name__ == '__main__':
    sys.exit(main())

"""The codebase keeps its shape: tools/check_shape.py finds no breach, and finds one."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location('check_shape', ROOT / 'tools' / 'check_shape.py')
check_shape = importlib.util.module_from_spec(spec)
spec.loader.exec_module(check_shape)


def test_no_function_module_or_document_is_over_its_limit():
    assert check_shape.breaches() == []


def test_each_kind_of_breach_is_found(tmp_path):
    pkg = tmp_path / 'extended_tracker'
    pkg.mkdir()
    long_body = '\n'.join(f'    x{i} = {i}' for i in range(61))
    (pkg / 'long.py').write_text(f'def f():\n    """Doc."""\n{long_body}\n')
    (pkg / 'big.py').write_text('x = 1\n' * 451)
    (pkg / 'private.py').write_text('from numpy._core.multiarray import c_einsum\n')
    (pkg / 'gen.py').write_text("exec('y = 1')\n")
    (tmp_path / 'README.md').write_text('x' * 20_001)
    (tmp_path / 'doc').mkdir()
    (tmp_path / 'doc' / 'notes.md').write_text('x' * 30_001)
    found = check_shape.breaches(tmp_path)
    assert len(found) == 6, found
    assert any('f: 61 lines' in f for f in found)
    # 60 lines of code, the docstring left out, is within the limit
    sixty = long_body.rsplit('\n', 1)[0]
    (pkg / 'long.py').write_text('def f():\n    """Doc."""\n' + sixty + '\n')
    assert not any('long.py' in f for f in check_shape.breaches(tmp_path))

"""
Where a picture goes: the ``--plot`` and ``--png`` names checked before a run, without
importing matplotlib (the bench checks its name before timing, and matplotlib loaded
first took some 10 MB more resident memory through the memory run).
"""

from __future__ import annotations

from pathlib import Path
import tempfile

from ..errors import PlotError

# the suffixes savefig writes (matplotlib's FigureCanvasBase.get_supported_filetypes() of
# the pinned release, which a test holds this to), less pgf: it needs a LaTeX install
IMAGE_SUFFIXES = ('avif', 'eps', 'gif', 'jpeg', 'jpg', 'pdf', 'png', 'ps', 'raw', 'rgba',
                  'svg', 'svgz', 'tif', 'tiff', 'webp')


def image_path(path) -> Path:
    """
    The file a picture asked for at ``path`` is written to, its folder made: checked
    before a run, so that a run of minutes does not end in a traceback at the plot.

    A name without a suffix gets ``.png`` (as savefig would add, said here so the caller
    can print the real name).

    Raises
    ------
    PlotError
        When ``path`` is a folder, its suffix names no format savefig writes, or its
        folder cannot be made or written in.
    """
    p = Path(path)
    if p.is_dir():
        raise PlotError(f'plot {p} is a folder: name an image file, e.g. {p / "run.png"}')
    if not p.suffix:
        p = p.with_name(p.name + '.png')
    if p.suffix[1:].lower() not in IMAGE_SUFFIXES:
        raise PlotError(f'plot {p}: {p.suffix!r} is not an image format written here; use '
                        f'one of {", ".join("." + s for s in IMAGE_SUFFIXES)}')
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        # a probe file: the picture is written after the run, which must not end there
        with tempfile.NamedTemporaryFile(dir=p.parent, prefix=f'.{p.name}.', suffix='.probe'):
            pass
    except OSError as err:
        msg = f'plot {p}: cannot write there: {err.strerror or err}'
        raise PlotError(msg) from err
    return p

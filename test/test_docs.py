"""The README's cross-references and links lead to something that is there."""

from pathlib import Path
import re

README = Path(__file__).resolve().parents[1] / 'README.md'

# "(see *Performance*)", "*Ids do not jump* below", "under *Known weaknesses* below"
REFERENCE = re.compile(r'(?:see |under )\*([^*]+)\*|(?<!\*)\*([^*]+)\*(?= below| above)')


def _targets(text: str):
    """The names a reference may give (headings, bold leads) and the paragraphs, whose
    first words may be one, all with whitespace folded."""
    heads = re.findall(r'^#+ (.*)$', text, re.M)
    flat = re.sub(r'\s+', ' ', text)
    bold = re.findall(r'\*\*([^*]+)\*\*', flat)
    paragraphs = [re.sub(r'\s+', ' ', p).strip() for p in re.split(r'\n\s*\n', text)]
    return {s.strip().rstrip('.:') for s in heads + bold}, paragraphs


def references(text: str) -> list[str]:
    flat = re.sub(r'\s+', ' ', text)
    return [a or b for a, b in REFERENCE.findall(flat)]


def dangling(text: str) -> list[str]:
    names, paragraphs = _targets(text)
    return [r for r in references(text)
            if r not in names and not any(p.startswith(r) for p in paragraphs)]


def test_every_section_the_readme_points_to_is_there():
    assert dangling(README.read_text()) == []


def test_every_file_the_readme_links_to_is_there():
    text = README.read_text()
    links = re.findall(r'\]\(([^)#]+)\)', text)
    assert 'doc/model.md' in links and 'doc/demo.png' in links
    missing = [link for link in links
               if '://' not in link and not (README.parent / link).exists()]
    assert missing == []


def test_a_reference_to_a_missing_section_is_found():
    text = ('Intro (see *Limits* below).\n\n## Usage\n\nRun it; see *Usage*.\n\n'
            'Limits, each measured:\n\n- one\n')
    assert dangling(text) == []
    assert dangling(text.replace('Limits, each', 'Each')) == ['Limits']

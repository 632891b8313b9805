"""The files an open-source project is expected to have, and one version everywhere."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

import toddlerbot

ROOT = Path(__file__).resolve().parents[1]


def test_the_version_is_one_and_the_changelog_and_citation_follow_it():
    from importlib.metadata import version

    assert version("toddlerbot") == toddlerbot.__version__  # pyproject reads it from the package
    releases = re.findall(r"^## \[(\d+\.\d+\.\d+)\] - \d{4}-\d{2}-\d{2}$", (ROOT / "CHANGELOG.md").read_text(), re.M)
    assert releases[0] == toddlerbot.__version__ and releases == sorted(releases, key=_key, reverse=True)
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert citation["version"] == toddlerbot.__version__ and citation["cff-version"] == "1.2.0"
    assert "arXiv:2502.00893" in {i["value"] for i in citation["preferred-citation"]["identifiers"]}


def test_the_licence_text_is_the_one_pyproject_declares():
    import tomllib

    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["license"]["text"]
    assert declared == "MIT" and (ROOT / "LICENSE").read_text().startswith("MIT License\n")


def test_contributing_points_at_the_guides_that_exist():
    text = (ROOT / "CONTRIBUTING.md").read_text()
    for guide in re.findall(r"(docs/[a-z_]+\.md|ARCHITECTURE\.md|CHANGELOG\.md)", text):
        assert (ROOT / guide).is_file(), guide
    headings = re.findall(r"^## (.+)$", (ROOT / "docs" / "extending.md").read_text(), re.M)
    for named in re.findall(r'docs/extending\.md, "([^"]+)"', text):
        assert named in headings, named


def _key(release: str) -> tuple[int, ...]:
    return tuple(int(part) for part in release.split("."))

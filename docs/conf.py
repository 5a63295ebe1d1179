"""Sphinx configuration of projection_server's documentation (``make docs``; rosdoc2 reads
it too, through ``rosdoc2.yaml``). Markdown pages (myst-parser), the furo theme, and the
reference made from the sources by ``_ext/projection_reference.py``. Builds offline."""

from __future__ import annotations

from pathlib import Path
import sys
import xml.etree.ElementTree as ET

here = Path(__file__).resolve().parent
sys.path.insert(0, str(here / '_ext'))

_package = ET.parse(here.parent / 'package.xml').getroot()
project = 'projection_server'
author = 'projection_server maintainers'
release = version = _package.findtext('version')
copyright = f'{_package.findtext("license")} license'

extensions = [
    'myst_parser',
    'sphinx.ext.autodoc',
    'projection_reference',
]
source_suffix = {'.md': 'markdown'}
root_doc = 'index'
exclude_patterns = ['_build', '_ext', 'contracts.md', 'README*']
myst_enable_extensions = ['colon_fence', 'deflist']
myst_heading_anchors = 3
suppress_warnings = []

autodoc_default_options = {'members': True, 'show-inheritance': False}
autodoc_member_order = 'bysource'
autodoc_typehints = 'description'
autodoc_mock_imports = []

html_theme = 'furo'
html_title = f'projection_server {release}'
html_static_path = []
# Nothing fetched while building: no intersphinx, no remote images or fonts.
intersphinx_mapping = {}

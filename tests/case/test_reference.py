"""docs/case-format.md lists every key of the schema with its default: the page holds the generated table."""

from femcrowd.case.reference import keys_markdown
from femcrowd.case.schema import SCHEMA

from ..support import ROOT


def test_the_case_format_page_lists_every_key_as_the_schema_has_it():
    page = (ROOT / "docs" / "case-format.md").read_text()
    block = page.split("<!-- keys: begin -->\n")[1].split("<!-- keys: end -->")[0]
    assert block == keys_markdown(), "regenerate with: python -m femcrowd.case.reference"
    for section, keys in SCHEMA.items():
        for name in keys if isinstance(keys, dict) else [None]:
            assert (f"`{section}.{name}`" if name else f"`{section}`") in block

"""Generated tables pasted between markers (``study.readme``): all blocks whose table exists,
or one block from a named file, never the text around them."""

from mfcl_jax.study.readme import update_block, update_readme

PAGE = (
    "intro\n<!-- BEGIN:x -->\nold x\n<!-- END:x -->\nmiddle\n"
    "<!-- BEGIN:y -->\nold y\n<!-- END:y -->\n"
)


def test_one_block_from_a_file_leaves_the_others(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(PAGE)
    (tmp_path / "table.md").write_text("new x\n")
    (tmp_path / "y.md").write_text("new y\n")  # present, but not asked for
    assert update_block(page, "x", tmp_path / "table.md")
    assert page.read_text() == PAGE.replace("old x", "new x")
    assert not update_block(page, "z", tmp_path / "table.md")  # no such block: untouched
    assert page.read_text() == PAGE.replace("old x", "new x")


def test_every_block_whose_table_exists(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(PAGE)
    (tmp_path / "y.md").write_text("new y\n")
    assert update_readme(page, tmp_path) == ["y"]
    assert page.read_text() == PAGE.replace("old y", "new y")

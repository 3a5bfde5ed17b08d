"""MkDocs hook: `experiments/results/RESULTS.md` on the site as it is in the repository.

The site shows it at `assets/results/RESULTS.md` (`docs/assets/results` links to
`experiments/results`), where its figures (beside it) resolve as they do on disk; its
links to the docs pages are written from `experiments/results/` (`../../docs/PAGE.md`), so
here they lose the `docs/`.
"""

RESULTS = "assets/results/RESULTS.md"


def on_page_markdown(markdown, page, **kwargs):
    if page.file.src_uri == RESULTS:
        return markdown.replace("](../../docs/", "](../../")
    return markdown

"""viser browser view of a finished pinquad run.

``python -m viz RUN_DIR`` serves it (see ``viz.__main__``); ``viz.app.serve`` builds the
same view without blocking. The package only reads what a run wrote (``report.json``,
``logs/``, ``figures/``) and imports viser lazily, so importing ``viz`` stays cheap.
"""

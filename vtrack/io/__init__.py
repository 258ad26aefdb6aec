"""Video input and output: sources (`sources`: files, streams, cameras), the supervised
decoder process and its frames (`video`), the annotated-video writer (`video_writer`).
Import the submodules directly; this package imports nothing heavy."""

"""The web viewer's default ports, apart from :mod:`cosim.viz.web_viewer` (which imports
``http.server``, ~0.03 s): the command line's options show them, and ``auv-cosim sweep``
starts its workers' fork server before it imports anything it does not need."""

WEB_PORT = 9090  # rerun's default for the web viewer's page
FILE_PORT = 9876  # the recording, served over HTTP by this process

"""The web page: rerun's gRPC server (the data) and its web viewer (HTML + Wasm from the rerun-sdk wheel).

Nothing is fetched from the internet: the viewer's files are in the wheel. The page's only outside link
(a web font) fails quietly offline and the viewer falls back to its built-in font.
"""

from __future__ import annotations

import socket
import urllib.parse
from dataclasses import dataclass

import rerun as rr

APPLICATION_ID = 'stylepong'
DEFAULT_WEB_PORT = 9090
DEFAULT_GRPC_PORT = 9876


class ServeError(RuntimeError):
    """The page cannot be served (a port taken); the message is one line."""


@dataclass(frozen=True)
class Page:
    """Where the page is."""

    url: str  # what a browser opens
    grpc_uri: str  # where the page reads the data


def _check_free(port: int, what: str) -> None:
    """rerun binds all interfaces; a port in use would only show later as a log line on its thread."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(('0.0.0.0', port))
        except OSError as error:
            raise ServeError(
                f'{what} port {port} is not free ({error.strerror}); choose another with --{what}-port'
            ) from error


def serve(
    recording: rr.RecordingStream,
    blueprint,
    web_port: int,
    grpc_port: int,
    memory_limit: str = '512MiB',
    host: str = '127.0.0.1',
) -> Page:
    """Start both servers for `recording` (they run on rerun's threads until the process ends)."""
    _check_free(web_port, 'web')
    _check_free(grpc_port, 'grpc')
    # Old data is dropped first when the server's memory limit is reached: a long session keeps its
    # latest minutes.
    grpc_uri = recording.serve_grpc(grpc_port=grpc_port, default_blueprint=blueprint, server_memory_limit=memory_limit)
    rr.serve_web_viewer(web_port=web_port, open_browser=False, connect_to=grpc_uri)
    grpc_uri = grpc_uri.replace('127.0.0.1', host).replace('0.0.0.0', host)
    url = f'http://{host}:{web_port}/?url={urllib.parse.quote(grpc_uri, safe="")}'
    return Page(url=url, grpc_uri=grpc_uri)

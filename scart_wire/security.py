"""Who may talk to a scart gRPC server, and how: TLS / mTLS, and bearer tokens with roles.

One frozen :class:`Security` value configures both ends of every gRPC surface (the
deployer, the name service, binding.grpc):

* **TLS** — ``cert`` + ``key`` (PEM files) make a server speak TLS; a client verifies the
  server with ``ca``. **mTLS** — a server given ``ca`` as well requires client
  certificates signed by it; a client presents ``cert`` + ``key``.
* **Tokens with roles** — a server given ``auth_file`` (lines ``ROLE TOKEN``, ``#``
  comments) checks the ``authorization: Bearer <token>`` metadata of every call; a client
  sends ``token``. Roles nest: ``read`` (introspection, reads, subscriptions, lookups) <
  ``operate`` (writes, calls, property sets, state changes, connections) < ``admin``
  (name registration by other deployers). No valid token: ``UNAUTHENTICATED``; a call the
  role does not allow: ``PERMISSION_DENIED`` naming the role it needs. A health check
  (``Health/Check``) stays open (it reveals nothing); ``Health/Watch``, a stream, needs
  ``read``. Tokens are compared in constant time and never logged. While a call runs,
  :data:`CALLER` holds a digest of its token, so per-peer bounds count a token as one
  peer (on loopback a connection is no identity: every local process shares the address).
* **Safe default** — with neither, a server listens on loopback only: binding another
  address without TLS *and* tokens is refused unless ``insecure`` (then a loud warning).

Environment (read by :meth:`Security.from_env`, used by the command line and by
``connect()`` when no ``security`` is given): ``SCART_TLS_CERT``, ``SCART_TLS_KEY``,
``SCART_TLS_CA``, ``SCART_TOKEN`` (or ``SCART_TOKEN_FILE``, read by the command line),
``SCART_AUTH_FILE``. Importing this module imports no gRPC; making credentials does.
"""

from __future__ import annotations

import contextvars
import dataclasses
import enum
import functools
import hashlib
import hmac
import ipaddress
import logging
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, TypeVar

from scart_wire.errors import DataflowError

if TYPE_CHECKING:
    import argparse

    import grpc

Req = TypeVar("Req")
Resp = TypeVar("Resp")
Out = TypeVar("Out")
In = TypeVar("In")

__all__ = [
    "AuthTable", "Role", "Security", "SecurityError", "add_arguments", "auth_interceptor", "from_args", "is_loopback",
    "roles_of_service", "tls_mismatch",
]

log = logging.getLogger(__name__)

MAX_PEM_BYTES = 1 << 20  #: largest certificate / key file read
MAX_AUTH_BYTES = 1 << 20  #: largest auth file read
ENV = MappingProxyType({"cert": "SCART_TLS_CERT", "key": "SCART_TLS_KEY", "ca": "SCART_TLS_CA",
                        "token": "SCART_TOKEN", "auth_file": "SCART_AUTH_FILE"})


class SecurityError(DataflowError):
    """Security settings that cannot be used (a missing file, a bad auth file, an unsafe bind)."""


class Role(enum.IntEnum):
    """What a token may do; each role includes the ones below it."""

    READ = 1
    OPERATE = 2
    ADMIN = 3

    @property
    def label(self) -> str:
        """The role's name in auth files and messages (``read``, ``operate``, ``admin``)."""
        return self.name.lower()


@dataclass(frozen=True)
class AuthTable:
    """Tokens and their roles (from an auth file). :meth:`role_of` compares in constant time."""

    entries: tuple[tuple[bytes, Role], ...]

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> AuthTable:
        """Parse ``path``: one ``ROLE TOKEN`` per line, ``#`` starts a comment. Raises
        :class:`SecurityError` naming the file and line (never echoing a token)."""
        text = _read_bounded(path, MAX_AUTH_BYTES, "auth file", private=True)
        entries: list[tuple[bytes, Role]] = []
        seen: dict[bytes, Role] = {}
        for number, raw in enumerate(text.splitlines(), start=1):
            line = raw.split("#", 1)[0].strip()
            if not line:
                continue
            parts = line.split()
            where = f"{path}:{number}"
            if len(parts) != 2:
                raise SecurityError(f"{where}: expected 'ROLE TOKEN' (roles: read, operate, admin)")
            role_name, token = parts
            try:
                role = Role[role_name.upper()]
            except KeyError:  # never echoed: role and token may be swapped
                known = Role.__members__.get(token.upper())
                hint = "role and token swapped? " if known is not None else ""
                raise SecurityError(f"{where}: the first word is not a role ({hint}expected 'ROLE TOKEN', roles: "
                                    "read, operate, admin)") from None
            if len(token) < 8:
                raise SecurityError(f"{where}: token too short (at least 8 characters; 32 random ones are better)")
            key = token.encode()
            if key in seen and seen[key] is not role:
                raise SecurityError(f"{where}: this token is given two roles")
            seen[key] = role
            entries.append((key, role))
        if not entries:
            raise SecurityError(f"{path}: no token (lines 'ROLE TOKEN')")
        return cls(tuple(entries))

    def role_of(self, token: str | None) -> Role | None:
        """The role of ``token``, or None; every entry is compared (no early exit)."""
        if not token:
            return None
        given = token.encode()
        found: Role | None = None
        for key, role in self.entries:
            if hmac.compare_digest(key, given):
                found = role
        return found


@dataclass(frozen=True)
class Security:
    """TLS files, the token a client sends, the auth file a server checks, and whether a
    non-loopback plaintext bind is allowed (see the module docstring). Frozen."""

    cert: str | None = None
    key: str | None = None
    ca: str | None = None
    token: str | None = field(default=None, repr=False)
    auth_file: str | None = None
    insecure: bool = False

    @classmethod
    def from_env(cls, environ: Mapping[str, str] | None = None, **given: Any) -> Security:  # Any: fields, to replace
        """Security from the ``SCART_TLS_*``, ``SCART_TOKEN`` and ``SCART_AUTH_FILE``
        variables; values in ``given`` that are not None win."""
        env = os.environ if environ is None else environ
        read = {name: (env.get(var) or None) for name, var in ENV.items()}  # every ENV field is a str | None
        base = cls(cert=read["cert"], key=read["key"], ca=read["ca"], token=read["token"], auth_file=read["auth_file"])
        return dataclasses.replace(base, **{k: v for k, v in given.items() if v is not None})

    @property
    def tls(self) -> bool:
        """True when a server speaks TLS (it has a certificate and key)."""
        return bool(self.cert and self.key)

    def check(self) -> None:
        """Raise :class:`SecurityError` for settings that cannot work together, and for a
        ``--tls-ca`` file holding no PEM certificate (gRPC would print its own lines and the
        CLI "nothing answers")."""
        if bool(self.cert) != bool(self.key):
            raise SecurityError("--tls-cert and --tls-key go together (a certificate and its private key)")
        if self.ca:
            _check_ca(self.ca)

    def auth_table(self) -> AuthTable | None:
        """The auth file's tokens (read now), or None without one."""
        return AuthTable.load(self.auth_file) if self.auth_file else None

    # ---- servers -------------------------------------------------------------------
    def server_credentials(self) -> grpc.ServerCredentials | None:
        """TLS credentials for a server (mTLS when ``ca`` is set), or None for plaintext."""
        import grpc

        self.check()
        cert, key = self.cert, self.key
        if not self.tls or cert is None or key is None:
            return None
        pair = (_read_bounded(key, MAX_PEM_BYTES, "TLS key").encode(),
                _read_bounded(cert, MAX_PEM_BYTES, "TLS certificate").encode())
        _check_key_pair(cert, key)
        root = _read_bounded(self.ca, MAX_PEM_BYTES, "TLS CA").encode() if self.ca else None
        return grpc.ssl_server_credentials([pair], root_certificates=root, require_client_auth=root is not None)

    def check_bind(self, address: str, what: str) -> None:
        """Refuse a plaintext or tokenless bind of a non-loopback ``address`` unless
        ``insecure`` (then warn). Raises :class:`SecurityError` naming the flags to use."""
        host = address.rpartition(":")[0].strip("[]")
        if is_loopback(host):
            return
        if self.tls and self.auth_file:
            return
        missing = " and ".join(x for x, ok in (("TLS (--tls-cert/--tls-key)", self.tls),
                                              ("tokens (--auth-file)", bool(self.auth_file))) if not ok)
        if not self.insecure:
            raise SecurityError(f"{what}: refusing to listen on {address} without {missing}: anyone on the "
                                "network could drive the robot; give them, listen on 127.0.0.1, or pass --insecure")
        log.warning("%s: listening on %s WITHOUT %s (--insecure): anyone who can reach this address can "
                    "read and drive every component", what, address, missing)

    # ---- clients -------------------------------------------------------------------
    def channel(self, address: str, options: Sequence[tuple[str, object]] = ()) -> grpc.Channel:
        """A channel to ``address``: TLS when ``ca`` or ``cert`` is set (mTLS with both),
        sending ``token`` with every call when there is one."""
        import grpc

        self.check()
        if self.ca or self.cert:
            root = _read_bounded(self.ca, MAX_PEM_BYTES, "TLS CA").encode() if self.ca else None
            key = _read_bounded(self.key, MAX_PEM_BYTES, "TLS key").encode() if self.key else None
            chain = _read_bounded(self.cert, MAX_PEM_BYTES, "TLS certificate").encode() if self.cert else None
            creds = grpc.ssl_channel_credentials(root_certificates=root, private_key=key, certificate_chain=chain)
            channel = grpc.secure_channel(address, creds, options=list(options))
        else:
            channel = grpc.insecure_channel(address, options=list(options))
        if self.token:
            return grpc.intercept_channel(channel, _token_interceptor_class()(self.token))
        return channel


def add_arguments(parser: argparse.ArgumentParser, *, server: bool, client: bool = True) -> None:
    """Add the security flags to an argparse ``parser``: ``--tls-cert``, ``--tls-key``,
    ``--tls-ca`` always; ``--token`` for clients; ``--auth-file`` and ``--insecure`` for
    servers. Each defaults to its environment variable (see :meth:`Security.from_args`)."""
    group = parser.add_argument_group("security (see the README's security section)")
    group.add_argument("--tls-cert", default=None, metavar="PEM",
                       help="certificate: a server speaks TLS; a client presents it (mTLS) ($SCART_TLS_CERT)")
    group.add_argument("--tls-key", default=None, metavar="PEM", help="private key of --tls-cert ($SCART_TLS_KEY)")
    group.add_argument("--tls-ca", default=None, metavar="PEM",
                       help="CA: a client verifies the server with it; a server requires client "
                            "certificates signed by it (mTLS) ($SCART_TLS_CA)")
    if client:
        group.add_argument("--token", default=None,
                           help="bearer token sent with every call ($SCART_TOKEN); other local users can see "
                                "a command line: prefer $SCART_TOKEN or --token-file")
        group.add_argument("--token-file", default=None, metavar="PATH",
                           help="read the bearer token from this file, first line ($SCART_TOKEN_FILE)")
    if server:
        group.add_argument("--auth-file", default=None, metavar="PATH",
                           help="tokens and roles a server accepts, one 'ROLE TOKEN' per line ($SCART_AUTH_FILE)")
        group.add_argument("--insecure", action="store_true",
                           help="allow listening on a non-loopback address without TLS and tokens")


def from_args(args: argparse.Namespace, environ: Mapping[str, str] | None = None) -> Security:
    """The :class:`Security` of parsed flags (see :func:`add_arguments`), each falling back
    to its environment variable. Raises :class:`SecurityError` for settings that cannot
    work together."""
    env = os.environ if environ is None else environ
    token = getattr(args, "token", None)
    token_file = getattr(args, "token_file", None) or (env.get("SCART_TOKEN_FILE") or None if token is None else None)
    if token is not None and getattr(args, "token_file", None):
        raise SecurityError("give --token or --token-file, not both")
    if token is not None:
        log.warning("--token on the command line is visible to other local users (ps, /proc): "
                    "prefer SCART_TOKEN or --token-file")
    elif token_file:
        token = read_token_file(token_file)
    security = Security.from_env(
        environ, cert=getattr(args, "tls_cert", None), key=getattr(args, "tls_key", None),
        ca=getattr(args, "tls_ca", None), token=token,
        auth_file=getattr(args, "auth_file", None), insecure=getattr(args, "insecure", False) or None)
    security.check()
    return security


def read_token_file(path: str | os.PathLike[str]) -> str:
    """The token in ``path``: its first line that is not blank nor a ``#`` comment.
    Raises :class:`SecurityError` naming the file (never echoing its content)."""
    for raw in _read_bounded(path, MAX_AUTH_BYTES, "token file", private=True).splitlines():
        line = raw.split("#", 1)[0].strip()
        if line:
            return line
    raise SecurityError(f"token file {path}: no token in it")


def _check_ca(ca: str) -> None:
    """Raise :class:`SecurityError` naming ``--tls-ca`` when ``ca`` is not a readable file of
    PEM certificates."""
    import ssl

    text = _read_bounded(ca, MAX_PEM_BYTES, "--tls-ca")
    if "-----BEGIN CERTIFICATE-----" not in text:
        raise SecurityError(f"--tls-ca {ca}: no PEM certificate in it (give the CA's certificate, a file "
                            "starting '-----BEGIN CERTIFICATE-----')")
    try:
        ssl.create_default_context(cadata=text)
    except (ssl.SSLError, ValueError) as exc:
        why = str(exc).split(" (_ssl.c")[0]  # OpenSSL's own words, without its source line
        raise SecurityError(f"--tls-ca {ca}: not a PEM CA certificate ({why})") from None


def _check_key_pair(cert: str, key: str) -> None:
    """Raise :class:`SecurityError` naming the flag to fix when ``key`` is not the private
    key of ``cert`` or either is not PEM (gRPC would only say "Failed to bind")."""
    import ssl

    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    try:
        context.load_cert_chain(cert, key, password="")  # an encrypted key fails here, never prompts
    except ssl.SSLError as exc:
        if "KEY_VALUES_MISMATCH" in str(exc) or "key values mismatch" in str(exc):
            raise SecurityError(f"--tls-key {key} is not the private key of --tls-cert {cert}: give the key made "
                                "with that certificate") from None
        raise SecurityError(f"--tls-cert {cert} / --tls-key {key}: not a PEM certificate and its unencrypted "
                            f"private key ({exc.reason or exc})") from None
    except OSError as exc:
        raise SecurityError(f"--tls-cert {cert} / --tls-key {key}: cannot read: {exc.strerror or exc}") from None


def tls_mismatch(address: str, details: str, timeout: float = 1.0) -> str | None:
    """Why a connection to ``address`` that failed with gRPC's ``details`` failed, when
    the two ends disagree about TLS: one line naming the flag that fixes it (None when
    that is not the cause). A server that closes the connection at once ("Socket closed")
    is asked with a TLS handshake of its own (at most ``timeout`` s) whether it speaks TLS
    and wants a client certificate."""
    if "WRONG_VERSION_NUMBER" in details or ("handshake" in details.lower() and "PROTOCOL" in details
                                             and "CERTIFICATE" not in details):
        return (f"{address} does not speak TLS: drop --tls-ca/--tls-cert (and $SCART_TLS_CA, $SCART_TLS_CERT) to "
                "talk to it in plaintext, or give that server --tls-cert/--tls-key")
    if "CERTIFICATE_VERIFY_FAILED" in details or "certificate verify failed" in details.lower():
        return (f"{address} speaks TLS with a certificate that --tls-ca does not trust: give --tls-ca (or "
                "$SCART_TLS_CA) the CA that signed it")
    if "Socket closed" not in details and "Connection reset" not in details:
        return None
    speaks = _speaks_tls(address, timeout)
    if speaks == "mtls":
        return (f"{address} wants a client certificate (mTLS): give --tls-cert/--tls-key signed by the CA it "
                "trusts, and --tls-ca (or $SCART_TLS_CERT, $SCART_TLS_KEY, $SCART_TLS_CA)")
    if speaks == "tls":
        return f"{address} speaks TLS and this client does not: give --tls-ca (or $SCART_TLS_CA) the server's CA"
    return None


def _speaks_tls(address: str, timeout: float) -> str | None:
    """``"tls"`` when a TLS handshake with ``host:port`` succeeds, ``"mtls"`` when the
    server then asks for a client certificate, None when it does not speak TLS."""
    import socket
    import ssl

    host, _, port = address.rpartition(":")
    if not port.isdigit() or not host:
        return None
    context = ssl.create_default_context()
    context.check_hostname = False
    context.verify_mode = ssl.CERT_NONE
    context.set_alpn_protocols(["h2"])
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout) as raw:
            with context.wrap_socket(raw) as tls:
                # TLS 1.3: a server wanting a client certificate refuses after the handshake
                # (it closes, or alerts), where another sends its HTTP/2 settings
                try:
                    return "tls" if tls.recv(1) else "mtls"
                except ssl.SSLError as exc:
                    return "mtls" if "CERTIFICATE" in str(exc).upper() else "tls"
                except OSError:  # nothing within the timeout: it waits for us, as a TLS server does
                    return "tls"
    except ssl.SSLError as exc:  # an alert from a TLS server (TLS 1.2 asks for the certificate in the handshake)
        if "WRONG_VERSION_NUMBER" in str(exc) or isinstance(exc, ssl.SSLEOFError):
            return None
        return "mtls" if "CERTIFICATE" in str(exc).upper() else "tls"
    except OSError:
        return None


def is_loopback(host: str) -> bool:
    """True for ``localhost``, 127.0.0.0/8 and ::1 (what only this machine can reach)."""
    if host in ("localhost", "localhost.localdomain"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _read_bounded(path: str | os.PathLike[str] | None, limit: int, what: str, private: bool = False) -> str:
    """Read a small regular text file; :class:`SecurityError` naming it when unusable.
    ``private``: it holds secrets, so warn when other users may read it."""
    if path is None:
        raise SecurityError(f"no {what} file given")
    p = Path(path)
    try:
        if not p.is_file():
            raise SecurityError(f"{what} {p}: not a regular file")
        with p.open("rb") as fh:
            if private and os.fstat(fh.fileno()).st_mode & 0o077:
                log.warning("%s %s can be read by other users: chmod 600 it", what, p)
            data = fh.read(limit + 1)
    except OSError as exc:
        raise SecurityError(f"{what} {p}: cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise SecurityError(f"{what} {p}: larger than {limit} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise SecurityError(f"{what} {p}: not UTF-8 text") from None


# ---- the interceptors (gRPC imported lazily, when one is made) -------------------------

@functools.cache
def _token_interceptor_class() -> type:
    """The client interceptor adding ``authorization: Bearer <token>`` to every call (made
    once, on first use, so that importing this module imports no gRPC)."""
    import collections

    import grpc

    class Details(collections.namedtuple(
            "Details", ("method", "timeout", "metadata", "credentials", "wait_for_ready", "compression")),
            grpc.ClientCallDetails):
        pass

    class TokenInterceptor(grpc.UnaryUnaryClientInterceptor, grpc.UnaryStreamClientInterceptor,
                           grpc.StreamUnaryClientInterceptor, grpc.StreamStreamClientInterceptor):
        def __init__(self, token: str) -> None:
            self._header = ("authorization", f"Bearer {token}")

        def _add(self, d: grpc.ClientCallDetails) -> grpc.ClientCallDetails:
            return Details(d.method, d.timeout, [*(d.metadata or ()), self._header], d.credentials,
                           getattr(d, "wait_for_ready", None), getattr(d, "compression", None))

        def intercept_unary_unary(self, continuation: Callable[[grpc.ClientCallDetails, Req], Out],
                                  details: grpc.ClientCallDetails, request: Req) -> Out:
            return continuation(self._add(details), request)

        def intercept_unary_stream(self, continuation: Callable[[grpc.ClientCallDetails, Req], Out],
                                   details: grpc.ClientCallDetails, request: Req) -> Out:
            return continuation(self._add(details), request)

        def intercept_stream_unary(self, continuation: Callable[[grpc.ClientCallDetails, Iterator[Req]], Out],
                                   details: grpc.ClientCallDetails, requests: Iterator[Req]) -> Out:
            return continuation(self._add(details), requests)

        def intercept_stream_stream(self, continuation: Callable[[grpc.ClientCallDetails, Iterator[Req]], Out],
                                    details: grpc.ClientCallDetails, requests: Iterator[Req]) -> Out:
            return continuation(self._add(details), requests)

        def __repr__(self) -> str:
            return "<token interceptor>"  # never the token

    return TokenInterceptor


def roles_of_service(full_name: str, reads: set[str], default: Role = Role.OPERATE,
                     overrides: Mapping[str, Role] | None = None) -> dict[str, Role]:
    """``{"/pkg.Service/Method": role}`` for a service: ``reads`` need ``read``, methods in
    ``overrides`` their role, the others ``default``. Methods come from the descriptor pool."""
    from google.protobuf import descriptor_pool

    service = descriptor_pool.Default().FindServiceByName(full_name)
    table = {}
    for method in service.methods:
        role = (overrides or {}).get(method.name) or (Role.READ if method.name in reads else default)
        table[f"/{full_name}/{method.name}"] = role
    return table


#: Methods anyone may call (their answers reveal nothing, and they end at once).
OPEN_SERVICES = ("/grpc.health.v1.Health/Check",)

#: Who the running call is, when the server checks tokens: ``token:<digest>`` (set by
#: :func:`auth_interceptor` around each call it lets through; "" otherwise).
CALLER: contextvars.ContextVar[str] = contextvars.ContextVar("scart_caller", default="")


def auth_interceptor(table: AuthTable, roles: Mapping[str, Role],
                     unknown: Role = Role.READ) -> grpc.ServerInterceptor:
    """A server interceptor checking the bearer token of every call against ``table``:
    ``roles`` maps a method path to the role it needs (health is open; any other method,
    e.g. reflection, needs ``unknown``)."""
    import grpc

    def required(method: str) -> Role | None:
        if method.startswith(OPEN_SERVICES):
            return None
        return roles.get(method, unknown)

    class Interceptor(grpc.ServerInterceptor):
        def intercept_service(
                self, continuation: Callable[[grpc.HandlerCallDetails], grpc.RpcMethodHandler[Req, Resp] | None],
                details: grpc.HandlerCallDetails) -> grpc.RpcMethodHandler[Req, Resp] | None:
            need = required(details.method)
            if need is None:
                return continuation(details)
            token = None
            for key, value in details.invocation_metadata or ():
                if key == "authorization" and isinstance(value, str) and value.startswith("Bearer "):
                    token = value[len("Bearer "):].strip()
            role = table.role_of(token)
            name = details.method.rpartition("/")[2]
            if role is None:
                return _denied(continuation(details), grpc.StatusCode.UNAUTHENTICATED,
                               f"{name}: no valid token (send 'authorization: Bearer <token>'; "
                               "scart: --token or SCART_TOKEN)")
            if role < need:
                return _denied(continuation(details), grpc.StatusCode.PERMISSION_DENIED,
                               f"{name} needs the '{need.label}' role; this token has '{role.label}'")
            assert token is not None
            return _as_caller(continuation(details), "token:" + hashlib.sha256(token.encode()).hexdigest()[:16])

    return Interceptor()


def _as_caller(handler: grpc.RpcMethodHandler[Req, Resp] | None,
               caller: str) -> grpc.RpcMethodHandler[Req, Resp] | None:
    """``handler`` with :data:`CALLER` set to ``caller`` while its behaviour runs."""
    import grpc

    if handler is None:
        return None

    def unary(behavior: Callable[[In, grpc.ServicerContext], Out]) -> Callable[[In, grpc.ServicerContext], Out]:
        def run(request: In, context: grpc.ServicerContext) -> Out:
            token = CALLER.set(caller)
            try:
                return behavior(request, context)
            finally:
                CALLER.reset(token)
        return run

    def streaming(behavior: Callable[[In, grpc.ServicerContext], Iterator[Out]],
                  ) -> Callable[[In, grpc.ServicerContext], Iterator[Out]]:
        def run(request: In, context: grpc.ServicerContext) -> Iterator[Out]:
            token = CALLER.set(caller)
            try:
                yield from behavior(request, context)
            finally:
                try:
                    CALLER.reset(token)
                except ValueError:  # closed from another thread's context: nothing to restore there
                    pass
        return run

    reads, writes = handler.request_deserializer, handler.response_serializer
    if handler.unary_unary is not None:
        return grpc.unary_unary_rpc_method_handler(unary(handler.unary_unary), reads, writes)
    if handler.unary_stream is not None:
        return grpc.unary_stream_rpc_method_handler(streaming(handler.unary_stream), reads, writes)
    if handler.stream_unary is not None:
        return grpc.stream_unary_rpc_method_handler(unary(handler.stream_unary), reads, writes)
    if handler.stream_stream is not None:
        return grpc.stream_stream_rpc_method_handler(streaming(handler.stream_stream), reads, writes)
    return handler


def _denied(handler: grpc.RpcMethodHandler[Req, Resp] | None, code: grpc.StatusCode,
            message: str) -> grpc.RpcMethodHandler[Req, Resp] | None:
    """A handler of the same shape as ``handler`` that ends the call with ``code``."""
    import grpc

    if handler is None:
        return None

    def abort(request_or_iterator: object, context: grpc.ServicerContext) -> None:
        context.abort(code, message)

    kinds = (
        (handler.unary_unary, grpc.unary_unary_rpc_method_handler),
        (handler.unary_stream, grpc.unary_stream_rpc_method_handler),
        (handler.stream_unary, grpc.stream_unary_rpc_method_handler),
        (handler.stream_stream, grpc.stream_stream_rpc_method_handler),
    )
    for present, make in kinds:
        if present is not None:
            return make(abort, request_deserializer=handler.request_deserializer,
                        response_serializer=handler.response_serializer)
    return handler

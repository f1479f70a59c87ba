"""The error tree of scart, and the codes of composite problems.

Every error scart raises derives from :class:`ScartError`. A composite that cannot be
loaded raises one :class:`ScdlError` listing **every** problem found, each a
:class:`Problem` with a stable ``code``: the OASIS SCA Assembly 1.1 conformance
statement it enforces (``ASM50001``...) where one applies, ``SCART-...`` otherwise.
Tools and tests match the code, never the wording.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

# --- codes: OASIS SCA Assembly 1.1 conformance statements -----------------------------
ASM_DUPLICATE_COMPONENT = "ASM50001"  # component names unique in a composite
ASM_DUPLICATE_SERVICE = "ASM50002"  # service names unique on a component
ASM_DUPLICATE_REFERENCE = "ASM50007"  # reference names unique on a component
ASM_MULTIPLICITY_NARROWING = "ASM50009"  # a component reference may only narrow the componentType multiplicity
ASM_DUPLICATE_COMPOSITE_SERVICE = "ASM60003"  # composite service names unique
ASM_DUPLICATE_COMPOSITE_REFERENCE = "ASM60006"  # composite reference names unique
ASM_NO_SUCH_SERVICE = "ASM50003"  # component <service> must exist in the componentType
ASM_SERVICE_INTERFACE = "ASM50004"  # a component service's declared interface is a subset of the implementation's
ASM_NO_SUCH_REFERENCE = "ASM50008"  # component <reference> must exist in the componentType
ASM_PROPERTY_VALUE = "ASM50027"  # a property value must parse as its declared type
ASM_SINGLE_VALUED = "ASM50032"  # a single-valued property takes at most one <value>
ASM_DUPLICATE_PROPERTY = "ASM50031"  # property names unique on a component
ASM_NO_SUCH_PROPERTY = "ASM50037"  # component <property> must exist in the componentType
ASM_MUST_SUPPLY = "ASM40011"  # mustSupply property without a value
ASM_MULTIPLICITY_0_1 = "ASM50039"  # 0..1 with more than one target
ASM_MULTIPLICITY_1_1 = "ASM50040"  # 1..1 without exactly one target
ASM_MULTIPLICITY_1_N = "ASM50041"  # 1..n without a target
ASM_PROPERTY_FILE = "ASM50045"  # property @file must be readable
ASM_PROMOTED_SERVICE = "ASM60004"  # composite service promotes an existing component service
ASM_PROMOTED_REFERENCE = "ASM60007"  # composite reference promotes existing component references
ASM_DUPLICATE_COMPOSITE_PROPERTY = "ASM60014"  # composite property names unique
ASM_NO_SUCH_COMPOSITE = "ASM60030"  # implementation.composite names a known composite
ASM_INCLUDE_UNKNOWN = "ASM60042"  # include names a known composite
ASM_INTERFACE_MISMATCH = "ASM60043"  # wire target interface is a superset of the source's
ASM_NO_SUCH_TARGET = "ASM60047"  # target/wire names no component or no such service
ASM_AMBIGUOUS_TARGET = "ASM60048"  # "Component" target with several services
ASM_NO_SUCH_BINDING = "ASM60050"  # a target "Component/Service/binding" names a binding the service has
ASM_SCHEMA = "ASM13001"  # the composite does not conform to the schema (SCA 1.0 <operation>, unknown attributes...)
ASM_CT_DUPLICATE_SERVICE = "ASM40003"  # service names unique in a componentType
ASM_CT_DUPLICATE_REFERENCE = "ASM40004"  # reference names unique in a componentType
ASM_CT_DUPLICATE_PROPERTY = "ASM40005"  # property names unique in a componentType
ASM_PROPERTY_TYPE = "ASM40007"  # a property @type names an XML Schema type
ASM_PROPERTY_ELEMENT = "ASM40008"  # a property @element names a global element declaration
ASM_CT_TYPE_AND_ELEMENT = "ASM40010"  # a componentType property has @type or @element, not both
ASM_REFERENCE_INTERFACE = "ASM50011"  # a component reference's interface is a compatible superset of the componentType's
ASM_TARGET_AND_BINDING = "ASM50026"  # a reference with @target has no <binding> naming its own endpoint
ASM_ELEMENT_VALUE = "ASM50029"  # a property value given as an element is an instance of its @element
ASM_VALUE_AND_CHILD = "ASM50033"  # a property has @value or <value> children, not both
ASM_COMPONENT_TYPE_AND_ELEMENT = "ASM50035"  # a component property has @type or @element, not both
ASM_PROPERTY_TYPE_MISMATCH = "ASM50036"  # a component property's type matches its componentType's
ASM_SOURCE_TYPE = "ASM50038"  # @source names a composite property of a compatible type
ASM_NON_OVERRIDABLE = "ASM50042"  # a 0..1/1..1 nonOverridable reference is not promoted
ASM_PROPERTY_FILE_FORMAT = "ASM50046"  # a @file document is <sca:values> of <value>s or global elements
ASM_COMPOSITE_SERVICE_INTERFACE = "ASM60005"  # a composite service's interface is a compatible subset of the promoted one's
ASM_PROMOTED_INTERFACES = "ASM60008"  # references promoted together have compatible interfaces
ASM_COMPOSITE_MULTIPLICITY = "ASM60011"  # a composite reference narrows, never widens, what it promotes
ASM_COMPOSITE_REFERENCE_INTERFACE = "ASM60012"  # a composite reference's interface is a compatible superset
ASM_COMPOSITE_TYPE_AND_ELEMENT = "ASM60040"  # a composite property has @type or @element, not both
ASM_INCLUDE_LOCAL = "ASM60041"  # a local="true" composite is included only into a local one
ASM_WSDL_INTERFACE = "ASM80001"  # interface.wsdl @interface names a WSDL 1.1 portType (ns#wsdl.porttype(Name))
ASM_CALLBACK_AGREES = "ASM80011"  # @callbackInterface agrees with the callback the interface itself declares
ASM_WSDL_CALLBACK = "ASM80016"  # interface.wsdl @callbackInterface names a WSDL 1.1 portType
ASM_WSDL_REMOTABLE = "ASM80017"  # interface.wsdl is remotable: remotable="false" is an error
ASM_DUPLICATE_BINDING = "ASM90002"  # binding names unique on a service or reference
ASM_SCA_BINDING_SERVICE_URI = "ASM90005"  # binding.sca on a service has no @uri
ASM_CONTRIBUTION_SCHEMA = "ASM12027"  # sca-contribution.xml conforms to its schema
ASM_UNRESOLVED = "ASM12021"  # an artifact a contribution needs cannot be resolved (imports included)

# --- codes: scart's own rules -------------------------------------------------------
SCART_XML = "SCART-X001"  # malformed XML
SCART_UNSAFE_XML = "SCART-X002"  # DOCTYPE / entities / too large
SCART_SCHEMA = "SCART-X003"  # element of urn:scart:1.0 violates the shipped XSD
SCART_UNKNOWN_ELEMENT = "SCART-X004"  # an element scart does not know
SCART_ARCHIVE = "SCART-X005"  # a ZIP contribution that cannot be read, is over a limit, or has an entry that would escape
SCART_IMPORT = "SCART-I001"  # implementation/interface class cannot be imported
SCART_MISSING_OPERATION = "SCART-I002"  # class lacks an operation of a declared service
SCART_ONEWAY_RETURNS = "SCART-I003"  # a one-way operation declares a return value
SCART_NOT_A_COMPONENT = "SCART-I004"  # implementation class is not usable
SCART_WSDL = "SCART-I005"  # a WSDL's sca:callback names no portType
SCART_CALLBACK_MISSING = "SCART-I006"  # caller lacks a method of the target's callback interface
SCART_COMPOSITE_CYCLE = "SCART-C001"  # implementation.composite / include cycle
SCART_UNKNOWN_KIND = "SCART-C002"  # implementation or binding kind not registered
SCART_BAD_SOURCE = "SCART-C003"  # property @source names no composite property
SCART_DUPLICATE_COMPOSITE = "ASM60001"  # a composite name is unique in its namespace (two files declare one QName)
SCART_OVERRIDE = "SCART-C005"  # --set names no component/property
SCART_SIDE_FILE = "SCART-C007"  # a componentType side file and its implementation disagree
SCART_WIRE_SOURCE = "SCART-C008"  # a <wire>'s @source names no component reference


#: How bad a :class:`Problem` is: "error" refuses the composite, "warning" only says so.
Severity = Literal["error", "warning"]


@dataclass(frozen=True)
class Problem:
    """One composite problem: ``code``, human ``message``, and where (``path``, ``line``).

    ``severity`` is "error" (the composite is refused) or "warning" (it loads; the warning
    is shown by ``scart validate`` and ``scart run``, logged by ``Runtime.from_file``)."""

    code: str
    message: str
    path: str
    line: int
    severity: Severity = "error"

    def __str__(self) -> str:
        said = f"warning: {self.message}" if self.severity == "warning" else self.message
        if self.line <= 0:  # no line to point at (a file that cannot be read, the command line)
            where = "" if self.path in self.message else f"{self.path}: "
            return f"{where}{said} [{self.code}]"
        return f"{self.path}:{self.line}: {said} [{self.code}]"


class ScartError(Exception):
    """Base class of every error raised by scart."""


class ScdlError(ScartError):
    """A composite (SCDL) is invalid: ``errors`` lists every problem, in file order.

    ``path`` and ``line`` are those of the first problem; ``str(error)`` lists each
    problem on its own line as ``path:line: message [CODE]``.
    """

    def __init__(self, errors: list[Problem]) -> None:
        if not errors:
            raise ValueError("ScdlError needs at least one problem")
        self.errors: list[Problem] = list(errors)
        self.unused_overrides: set[str] = set()  # filled by ``assemble(..., strict_overrides=False)``
        self.warnings: list[Problem] = []  # warnings found beside the errors (filled by ``assemble``)
        self.path: str = errors[0].path
        self.line: int = errors[0].line
        super().__init__("\n".join(str(p) for p in self.errors))

    @property
    def codes(self) -> list[str]:
        """The codes of all problems, in order."""
        return [p.code for p in self.errors]


class RuntimeStateError(ScartError):
    """An operation is not allowed in the runtime's current lifecycle state."""


class ServiceNotFoundError(ScartError, KeyError):
    """``Runtime.service(name)`` names no service; the message lists what exists."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class NoCallbackError(ScartError):
    """``scart.callback()`` was used outside a call made by a component with a callback."""


class InvocationError(ScartError):
    """A call through a binding failed (``remote_type`` names the original error's type)."""

    def __init__(self, message: str, remote_type: str = "") -> None:
        super().__init__(message)
        self.remote_type = remote_type


class RemoteError(InvocationError):
    """An operation raised on the other side of a remote binding (``binding.grpc``).

    ``remote_type`` is the qualified type name of the remote exception (e.g.
    "ZeroDivisionError", "mymodule.Rejected"), ``remote_message`` its message,
    ``remote_code`` what kind of fault it is (``INVALID_ARGUMENT``, ``NOT_FOUND``,
    ``FAILED``, ``UNAVAILABLE``) and ``reference`` the name under which the other side
    logged its traceback (which never crosses the wire)."""

    def __init__(self, where: str, remote_type: str, remote_message: str, *, code: str = "",
                 reference: str = "") -> None:
        ref = f" (reference {reference} in the server's log)" if reference else ""
        super().__init__(f"{where}: remote {remote_type}: {remote_message}{ref}", remote_type)
        self.remote_message = remote_message
        self.remote_code = code
        self.reference = reference


class ServiceUnavailableError(InvocationError):
    """A remote service could not be reached, or did not answer, within the deadline
    (the message names the address and the deadline)."""

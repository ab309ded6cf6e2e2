"""What the SSP 1.0 reader and writer share: namespaces, annotation types, schema validation.

SSP (System Structure and Parameterization, Modelica Association, 1.0) packs a system of FMUs
into one zip archive: ``SystemStructure.ssd`` (components, connectors, connections with
``ssc:LinearTransformation``, parameter bindings, default experiment) and the FMUs under
``resources/``. What SSP 1.0 cannot say (communication step, master algorithm, ME solver
options, multi-rate, recorded variables, result file) travels in annotations of type
:data:`ANNOTATION_TYPE`, whose attributes carry the YAML scenario's key names; the
communication step and multi-rate are also written as OSP annotations, which libcosim reads.

C++ importers (libcosim, Ecos) match element names with their prefixes literally, so the
writer declares the standard prefixes ``ssd``, ``ssc``, ``ssv`` on the root element.
"""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path
from typing import List, Tuple

from lxml import etree

__all__ = ["ANNOTATION_TYPE", "FMU_MIME_TYPE", "NAMESPACES", "OSP_ANNOTATION_TYPE", "PARAMETER_SET_MIME_TYPE",
           "SSD_NAME", "schema_problems", "tag"]

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
DELTAFMI = "https://github.com/deltafmi/deltafmi/ssp-annotations"
NAMESPACES = {"ssd": SSD, "ssc": SSC, "ssv": SSV, "osp": OSP, "dfmi": DELTAFMI}

#: ``ssc:Annotation type`` of deltafmi's own annotations (reverse domain name, as SSP asks)
ANNOTATION_TYPE = "com.deltafmi"
#: the annotation type libcosim reads (its fixed-step algorithm and step size hints)
OSP_ANNOTATION_TYPE = "com.opensimulationplatform"
#: the SSD every SSP archive has at its root
SSD_NAME = "SystemStructure.ssd"
FMU_MIME_TYPE = "application/x-fmu-sharedlibrary"
PARAMETER_SET_MIME_TYPE = "application/x-ssp-parameter-set"


def tag(prefix: str, name: str) -> str:
    """``{namespace}name`` for lxml, from a prefix of :data:`NAMESPACES`."""
    return f"{{{NAMESPACES[prefix]}}}{name}"


@lru_cache(maxsize=None)
def _schema(file_name: str) -> etree.XMLSchema:
    """One of the SSP 1.0 XSDs that fmpy ships (fmpy/ssp/schema)."""
    import fmpy.ssp
    return etree.XMLSchema(file=str(Path(fmpy.ssp.__file__).parent / "schema" / file_name))


def schema_problems(element: etree._Element, kind: str = "ssd") -> List[Tuple[int, str]]:
    """(line, message) of every violation of the SSP 1.0 schema by ``element``: a whole SSD
    (``kind="ssd"``) or an ``ssv:ParameterSet`` (``kind="ssv"``, also one inlined in an SSD)."""
    schema = _schema({"ssd": "SystemStructureDescription.xsd",
                      "ssv": "SystemStructureParameterValues.xsd"}[kind])
    if schema.validate(element):
        return []
    return [(entry.line, _prefixed(entry.message)) for entry in schema.error_log]


def _prefixed(message: str) -> str:
    """lxml names elements ``{uri}Name``; say ``ssd:Name`` as the file does."""
    by_uri = {uri: prefix for prefix, uri in NAMESPACES.items()}
    return re.sub(r"\{([^}]*)\}", lambda m: f"{by_uri[m[1]]}:" if m[1] in by_uri else m[0], message)

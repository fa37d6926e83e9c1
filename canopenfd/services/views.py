"""What services see of the nodes they belong to.

Services hold their node for its public face only (`request.node`,
`value.node`, `emcy.node`, `pdo_map.node`) and to ask whether it booted;
these Protocols say exactly that, so services never import the node module
that builds them.
"""

from __future__ import annotations

from typing import Optional, Protocol

from ..od import ObjectDictionary

__all__ = ["NodeView", "LocalNodeView", "RemoteNodeView"]


class NodeView(Protocol):
    node_id: int


class LocalNodeView(NodeView, Protocol):
    """The local node: the OD it serves and whether it booted."""

    od: Optional[ObjectDictionary]

    @property
    def booted(self) -> bool:
        ...


class RemoteNodeView(NodeView, Protocol):
    """A remote node: the OD that names and types its entries."""

    @property
    def object_dictionary(self) -> Optional[ObjectDictionary]:
        ...

"""The 3-D weft model's geometry (docs/weft3d.md): loops as inextensible space curves
(``curve3d``), the natural 3-D loop with the plain-knit order at its crossings (``natural3d``)
and the persistent sliding contacts of the designed crossings (``crossing_contact``)."""

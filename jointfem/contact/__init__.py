"""Contact laws behind one interface (jointfem.contact.law.ContactLaw).

A new law is one file with one ContactLaw class, and one entry here.
"""
from .cubic import CubicSprings
from .jenkins import JenkinsPairs
from .law import ContactError, ContactLaw, ContactResult  # noqa: F401
from .unilateral import UnilateralSprings

LAWS: dict[str, type[ContactLaw]] = {
    JenkinsPairs.name: JenkinsPairs,
    UnilateralSprings.name: UnilateralSprings,
    CubicSprings.name: CubicSprings,
}

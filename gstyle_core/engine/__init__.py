"""The G-Style stylization engine: one ``Stylizer.step()`` call = one step of one phase."""

"""twolink: a MuJoCo testbed for Busoniu, De Schutter & Babuska (ICARCV 2006)."""
__version__ = "0.1.0"

"""Test rooms rendered independently of trackerd's own simulator, to test trackerd on images it was not tuned on
(README.md here)."""

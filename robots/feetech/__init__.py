"""Feetech STS serial bus servos as the SO-101 arm carries them (six STS3215 on one half-duplex line): their
packets (`packets`), their register map (`control_table`) and servos that answer as the real ones do (`servos`),
so that an unmodified driver (Feetech's SDK, LeRobot's `FeetechMotorsBus`) can talk to a simulated arm."""

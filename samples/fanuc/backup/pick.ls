/PROG  PICK
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "pick at UF 1";
PROG_SIZE	= 0;
CREATE		= DATE 26-11-20  TIME 10:00:00;
MODIFIED	= DATE 26-11-20  TIME 10:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 4;
MEMORY_SIZE	= 0;
PROTECT		= READ_WRITE;
TCD:  STACK_SIZE	= 0,
      TASK_PRIORITY	= 50,
      TIME_SLICE	= 0,
      BUSY_LAMP_OFF	= 0,
      ABORT_REQUEST	= 0,
      PAUSE_REQUEST	= 0;
DEFAULT_GROUP	= 1,*,*,*,*;
CONTROL_CODE	= 00000000 00000000;
/MN
   1:L P[1] 200mm/sec CNT20 ;
   2:L P[2] 50mm/sec FINE ;
   3:  PR[20:PICK LPOS]=LPOS ;
   4:L P[1] 200mm/sec CNT20 ;
/POS
P[1]{
   GP1:
	UF : 1, UT : 2,		CONFIG : 'N U T, 0, 0, 0',
	X =   420.000  mm,	Y =    80.000  mm,	Z =    60.000  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =    15.000 deg
};
P[2]{
   GP1:
	UF : 1, UT : 2,		CONFIG : 'N U T, 0, 0, 0',
	X =   420.000  mm,	Y =    80.000  mm,	Z =    12.250  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =    15.000 deg
};
/END

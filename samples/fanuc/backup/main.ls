/PROG  MAIN
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "cell cycle";
PROG_SIZE	= 0;
CREATE		= DATE 26-11-20  TIME 10:00:00;
MODIFIED	= DATE 26-11-20  TIME 10:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 8;
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
   1:  UFRAME_NUM=1 ;
   2:  UTOOL_NUM=2 ;
   3:J PR[1:HOME] 30% FINE ;
   4:L P[1:above pick] 500mm/sec CNT50 Tool_Offset,PR[16] ;
   5:L P[2] 100mm/sec FINE Tool_Offset,PR[15] ;
   6:  CALL PICK ;
   7:  CALL PLACE ;
   8:J PR[1:HOME] 30% FINE ;
/POS
P[1]{
   GP1:
	UF : 1, UT : 2,		CONFIG : 'N U T, 0, 0, 0',
	X =   310.000  mm,	Y =   120.000  mm,	Z =    45.000  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =     0.000 deg
};
P[2]{
   GP1:
	UF : 1, UT : 2,		CONFIG : 'N U T, 0, 0, 0',
	X =   310.000  mm,	Y =   120.000  mm,	Z =     5.500  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =     0.000 deg
};
/END

/PROG  PLACE
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "place at UF 2";
PROG_SIZE	= 0;
CREATE		= DATE 26-11-20  TIME 10:00:00;
MODIFIED	= DATE 26-11-20  TIME 10:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 9;
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
   1:  UFRAME_NUM=2 ;
   2:  UTOOL_NUM=3 ;
   3:  IF R[5:PLACE MODE]=1,JMP LBL[1] ;
   4:L P[1] 200mm/sec FINE ;
   5:  LBL[1] ;
   6:L P[2] 200mm/sec CNT30 ;
   7:L P[3] 50mm/sec FINE ;
   8:  UFRAME_NUM=1 ;
   9:  UTOOL_NUM=2 ;
/POS
P[1]{
   GP1:
	UF : 2, UT : 3,		CONFIG : 'N U T, 0, 0, 0',
	X =   150.000  mm,	Y =   -60.000  mm,	Z =   200.000  mm,
	W =   175.000 deg,	P =     5.000 deg,	R =   -20.000 deg
};
P[2]{
   GP1:
	UF : 2, UT : 3,		CONFIG : 'N U T, 0, 0, 0',
	X =   220.000  mm,	Y =   -40.000  mm,	Z =    80.000  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =   -30.000 deg
};
P[3]{
   GP1:
	UF : 2, UT : 3,		CONFIG : 'N U T, 0, 0, 0',
	X =   220.000  mm,	Y =   -40.000  mm,	Z =    20.000  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =   -30.000 deg
};
/END
